"""``python -m train.export RUN --format onnx`` (``train.run.onnx_export``): onnxruntime gives
the JAX actor's decisions on more than 10,000 observations recorded from episodes (greedy
actions identical, logits within 1e-5), for feed-forward, GRU and LSTM-PPO actors, GO/STOP
and continuous heads, with the others encoders, the memory carried by the caller; the sidecar
names the observation layout, the action meaning and the provenance."""

from __future__ import annotations

import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_transfer import tiny_run

import sgjax
from train.export import main
from train.run.onnx_export import OnnxActor, decision_function, load_actor

ENVS, STEPS = 64, 80  # 64 environments x 2 robots x 80 steps = 10,240 observations


def recorded_observations(run: Path) -> np.ndarray:
    """``[STEPS, ENVS * 2, D]``: observations of episodes played by random GO/STOP robots
    in the run's own environment (auto-resets keep every row real)."""
    from train.run.checkpoint import read, resolve

    config, _, _ = read(resolve(run))
    env, params = sgjax.make(config.env.scenarios[0], options=config.env.options,
                             num_agents=2, max_agents=config.env.slots)
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(
        jax.random.split(jax.random.key(0), ENVS), params)
    shape = (ENVS, config.env.slots) + ((env.config.action_dim,) if
                                         env.config.action_mode == "continuous" else ())

    def step(carry, key):
        obs, state = carry
        k_act, k_step = jax.random.split(key)
        actions = (jax.random.uniform(k_act, shape, minval=-1.0, maxval=1.0) if len(shape) > 2
                   else jax.random.bernoulli(k_act, 0.3, shape).astype(jnp.int32))
        obs, state, *_ = env.step_batch(jax.random.split(k_step, ENVS), state, actions, params)
        return (obs, state), obs

    _, seen = jax.jit(lambda c: jax.lax.scan(step, c, jax.random.split(
        jax.random.key(1), STEPS)))((obs, state))
    return np.asarray(seen).reshape(STEPS, -1, seen.shape[-1])


@pytest.mark.parametrize("network, env", [
    ({"kind": "mlp"}, {}),
    pytest.param({"kind": "gru", "recurrent_size": 16}, {}, marks=pytest.mark.slow),
    pytest.param({"kind": "lstm", "recurrent_size": 16, "others_encoder": "lstm",
                  "encoder_size": 8}, {"observations": "cadrl"}, marks=pytest.mark.slow),
    ({"kind": "mlp", "others_encoder": "attention", "encoder_size": 8},
     {"observations": "cadrl", "action_mode": "continuous"}),
], ids=["mlp", "gru", "lstm_ppo_others_lstm", "attention_continuous"])
def test_onnxruntime_decides_as_jax_on_recorded_observations(tmp_path, network, env):
    run = tiny_run(tmp_path / "run", num_seeds=2, **env)
    config_path = run / "checkpoints" / "latest.msgpack"
    from train.run.checkpoint import read

    config, _, _ = read(config_path)
    if network:  # a run of this network: re-save the tiny run with it
        from test_train import tiny

        from train.algorithm.trainer import Trainer, seed_keys
        from train.run.checkpoint import save

        config = tiny(seed=0, num_seeds=2, env={"time_limit": 20.0, **env},
                      network={"hidden": [32], **network})
        trainer = Trainer(config)
        runner = jax.jit(jax.vmap(trainer.init))(seed_keys(config))
        save(config_path, config, runner, {}, trainer.actor)
    out = tmp_path / "actor.onnx"
    main([str(run), "--format", "onnx", "--out", str(out), "--seed-index", "1"])
    _, config, layout, weights, index = load_actor(run, 1)
    assert index == 1
    decide = jax.jit(decision_function(config.network, layout, weights))
    observations = recorded_observations(run)
    assert observations.shape[0] * observations.shape[1] >= 10_000
    rows = json.loads(out.with_suffix(".json").read_text())["network"]["rows"]
    if rows != "any":  # a fixed row count: the robots of one environment at a time
        observations = observations.reshape(-1, rows, observations.shape[-1])[:5000]
    rows = observations.shape[1]
    memory_j = memory_o = (np.zeros((rows, json.loads(out.with_suffix(".json").read_text())[
        "network"]["memory"]), np.float32) if config.network.recurrent else None)
    onnx_actor = OnnxActor(out)
    for t in range(observations.shape[0]):
        if memory_j is None:
            head_j, action_j = decide(observations[t])
            head_o, action_o = onnx_actor(observations[t])
        else:
            head_j, action_j, memory_j = decide(observations[t], memory_j)
            head_o, action_o, memory_o = onnx_actor(observations[t], memory_o)
            np.testing.assert_allclose(memory_o, np.asarray(memory_j), atol=1e-5)
        np.testing.assert_allclose(head_o, np.asarray(head_j), atol=1e-5, rtol=1e-5)
        if layout.discrete:
            tie = np.abs(np.asarray(head_j)[:, 0] - np.asarray(head_j)[:, 1]) < 1e-5
            assert np.array_equal(action_o[~tie], np.asarray(action_j)[~tie])
        else:
            np.testing.assert_allclose(action_o, np.asarray(action_j), atol=1e-5)


def test_the_sidecar_names_layout_action_and_provenance(tmp_path):
    run = tiny_run(tmp_path / "run", num_seeds=1)
    main([str(run), "--out", str(tmp_path / "a.onnx")])
    note = json.loads((tmp_path / "a.json").read_text())
    assert note["schema"] == "sgjax.onnx_actor/1"
    assert note["inputs"] == ["observation"] and note["outputs"] == ["logits", "action"]
    terms = note["observation"]["terms"]
    assert terms[0]["start"] == 0 and terms[-1]["stop"] == note["observation"]["size"]
    assert all(a["stop"] == b["start"] for a, b in zip(terms, terms[1:], strict=False))
    assert note["action"]["values"] == {"0": "GO", "1": "STOP"}
    assert len(note["checkpoint"]["sha256"]) == 64 and note["trained_on"] == ["open"]
    assert {"git", "versions", "machine"} <= set(note["provenance"])


def test_a_missing_run_is_refused_by_name(tmp_path):
    with pytest.raises(SystemExit, match="no checkpoints/latest.msgpack in this folder"):
        main([str(tmp_path), "--out", str(tmp_path / "a.onnx")])


def test_an_acting_copy_acts_as_the_full_checkpoint(tmp_path):
    from sgjax.evaluation.evaluate import params_by_count, run_episodes
    from train.run.checkpoint import load_checkpoint_policy

    run = tiny_run(tmp_path / "run", num_seeds=2)
    full = run / "checkpoints" / "latest.msgpack"
    slim = tmp_path / "acting.msgpack"
    main([str(run), "--format", "acting", "--out", str(slim)])
    assert slim.stat().st_size < full.stat().st_size
    env, by_count = params_by_count("open", [2])
    for path in (full, slim):
        policy = load_checkpoint_policy(path, env, seed_index=1, deterministic=True)
        values = run_episodes(env, by_count[2], policy, jax.random.key(0), 4).values
        if path == full:
            expected = values
    for name in ("team_success", "episode_length", "collisions"):
        np.testing.assert_array_equal(values[name], expected[name])


def test_a_checkpoint_from_before_replayed_people_resumes(tmp_path):
    """A runner state saved before ``HumanState.replay`` existed (no such key under the
    environments' pedestrians) restores, the field None as it was."""
    from flax import serialization

    from train.algorithm.trainer import Trainer
    from train.run.checkpoint import read, restore

    run = tiny_run(tmp_path / "run", num_seeds=1, num_humans=2)
    path = run / "checkpoints" / "latest.msgpack"
    payload = serialization.msgpack_restore(path.read_bytes())
    humans = payload["runner"]["env_states"]["0"]["humans"]  # scenario 0's environments
    assert "replay" in humans
    del humans["replay"]
    path.write_bytes(serialization.msgpack_serialize(payload))
    config, _, _ = read(path)
    state, _ = restore(path, Trainer(config))
    assert state.env_states[0].humans.replay is None
