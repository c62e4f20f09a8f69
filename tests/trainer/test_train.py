"""The trainer: it learns, checkpoints round-trip and resume the same run, configs are
validated, a vmap over sixteen seeds equals separate seeds and never hangs (the commands end to
end: tests/trainer/test_train_commands.py)."""

import functools
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import yaml
from flax import serialization
from jaxprs import equations

from sgjax.environment.options import MakeOptions
from sgjax.evaluation.policies import load_policy, policy_options
from sgjax.terms.base import ConfigError
from train.algorithm import learner as learning
from train.algorithm import losses, rollout
from train.algorithm import trainer as trainer_module
from train.algorithm.actor import ActorWeights
from train.algorithm.config import config_from_dict, load_config
from train.algorithm.networks import ResetGRU, ResetLSTM
from train.algorithm.state import Rollout, RunnerState
from train.algorithm.trainer import Trainer, seed_keys
from train.run import checkpoint

ROOT = Path(__file__).resolve().parents[2]

TINY = {
    "env": {"scenarios": ["open"], "curriculum": [[0, 2]], "observations": "default"},
    "algorithm": {"num_envs": 8, "num_steps": 8, "total_steps": 8 * 8 * 3, "update_epochs": 2,
                  "num_minibatches": 2},
    "network": {"hidden": [32]},
}


def tiny(**sections):
    data = {k: dict(v) for k, v in TINY.items()}
    for section, values in sections.items():
        if isinstance(values, dict):
            data.setdefault(section, {}).update(values)
        else:
            data[section] = values
    return config_from_dict(data, "test")


def leaves_close(a, b, **tol):
    return all(np.allclose(x, y, **tol) for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b),
                                                          strict=True))


@pytest.mark.slow
def test_a_tiny_run_learns_to_reach_the_goal():
    """One robot in the open with continuous actions: success rises from near zero."""
    config = tiny(env={"curriculum": [[0, 1]], "action_mode": "continuous", "time_limit": 20.0,
                       "observations": "default"},
                  algorithm={"num_envs": 64, "num_steps": 32, "total_steps": 64 * 32 * 60,
                             "learning_rate": 1e-3, "ent_coef": 0.0, "update_epochs": 4,
                             "num_minibatches": 4})
    trainer = Trainer(config)
    chunk = jax.jit(lambda r: trainer.update_chunk(r, 15))
    runner = trainer.init(jax.random.PRNGKey(0))
    rates = []
    for _ in range(4):
        runner, logs = chunk(runner)
        rates.append(float(logs["robot_successes"].sum() / max(logs["robots"].sum(), 1)))
    assert rates[0] < 0.35 and rates[-1] > 0.85, rates


@pytest.mark.parametrize("data, message", [
    ({"algorithm": {"totl_steps": 5}}, "did you mean 'total_steps'"),
    ({"algorthm": {}}, "did you mean 'algorithm'"),
    ({"algorithm": {"num_envs": "many"}},
     r"bad.yaml: algorithm.num_envs must be an integer, got 'many'"),
    ({"env": {"curriculum": [[5, 2]]}}, "curriculum must be"),
    ({"network": {"kind": "transformer"}}, "kind must be one of"),
    ({"env": {"num_arcz": 5}}, "env: unknown key 'num_arcz' \\(did you mean 'num_arcs'\\?\\)"),
    ({"env": {"num_agents": 5}}, "unknown key 'num_agents'.*valid keys are: scenarios"),
    ({"env": {"human_model": "orka"}}, "env: human_model must be one of"),
    ({"env": {"dt": -1}}, "env: dt must be a positive number"),
    ({"algorithm": {"lanes": "parallel"}}, r"algorithm: lanes must be one of \('auto', 'batch"),
    ({"algorithm": {"gamma": 1.5}}, r"algorithm: gamma must be in \[0, 1\], got 1.5"),
    ({"env": {"curriculum": [[0, 2.5]]}}, r"env.curriculum\[0\]\[1\] must be an integer"),
    ({"env": {"options": {"robot": {}}}}, r"env.options: unknown group 'robot' \(did you mean"),
    ({"env": {"options": {"humans": {"num_human": 2}}}},
     r"env.options.humans: unknown option 'num_human' \(did you mean 'num_humans'"),
    ({"env": {"options": {"robots": {"max_agents": 8}}}}, "robot counts are curriculum"),
    ({"seed": 1.5}, "bad.yaml: seed must be an integer, got 1.5"),
])
def test_the_config_validator_rejects_bad_keys(data, message):
    with pytest.raises(ConfigError, match=message):
        config_from_dict(data, "bad.yaml")


@pytest.mark.slow
def test_command_line_overrides_and_shipped_configs():
    config = load_config(ROOT / "train/configs/doorway.yaml",
                         ["algorithm.total_steps=1000", "env.curriculum=[[0, 3], [500, 5]]"])
    assert config.algorithm.total_steps == 1000 and config.env.slots == 5
    assert config.env.num_agents_at(499) == 3 and config.env.num_agents_at(500) == 5
    for path in sorted((ROOT / "train/configs").glob("*.yaml")):
        loaded = load_config(path)
        Trainer(loaded)  # builds every scenario and checks the shapes fit
    with pytest.raises(ConfigError, match="no such config"):
        load_config(ROOT / "train/configs/nope.yaml")
    from train.ablation import _variant_config, load_variants

    for path in sorted((ROOT / "train/configs/variants").glob("*.yaml")):
        # the config it varies: doorway.yaml, intersection-hold.yaml -> intersection.yaml
        config = load_config(ROOT / "train/configs" / f"{path.stem.split('-')[0]}.yaml")
        for variant in load_variants(path).values():  # every variant is a valid config
            Trainer(_variant_config(config, variant, 2))


def test_numbers_in_exponent_form_read_as_numbers(tmp_path):
    # PyYAML reads "2e6" as a string (YAML 1.1); the config reader takes it as YAML 1.2 does,
    # a whole mantissa with a non-negative exponent as an int
    config = load_config(ROOT / "train/configs/doorway.yaml",
                         ["algorithm.total_steps=2e6", "seed=3e0", "algorithm.learning_rate=3E-4",
                          "env.curriculum=[[0, 3], [1e5, 5]]", "evaluation.every=5e5"])
    assert config.algorithm.total_steps == 2_000_000
    assert type(config.algorithm.total_steps) is int and type(config.seed) is int
    assert config.seed == 3 and config.algorithm.learning_rate == pytest.approx(3e-4)
    assert config.env.curriculum == ((0, 3), (100_000, 5))
    assert type(config.env.curriculum[1][0]) is int and config.evaluation.every == 500_000
    for bad, shown in (("2.5", "2.5"), ("2e6x", "'2e6x'"), ("1e-3", "0.001")):
        with pytest.raises(ConfigError,
                           match=f"algorithm.total_steps must be an integer, got {shown}"):
            load_config(ROOT / "train/configs/doorway.yaml", [f"algorithm.total_steps={bad}"])
    from train.ablation import load_variants

    variants = tmp_path / "variants.yaml"
    variants.write_text("baseline: {}\nlonger:\n  set: {algorithm.total_steps: 4e6}\n")
    assert dict(load_variants(variants)["longer"].settings) == {"algorithm.total_steps": 4e6}


def test_env_section_takes_every_make_option_and_round_trips():
    config = config_from_dict({"env": {"num_arcs": 7, "human_model": "helbing", "num_humans": 2,
                                       "max_agents": 6, "curriculum": [[0, 3]]}})
    assert config.env.slots == 6
    assert config.env.options == MakeOptions.from_keywords(
        num_arcs=7, human_model="helbing", num_humans=2, observations="navigation")
    assert config_from_dict(config.to_dict()) == config
    # the options travel nested (MakeOptions.to_dict), defaults included
    assert config.to_dict()["env"]["options"] == config.env.options.to_dict()
    assert config.to_dict()["env"]["options"]["physics"]["dt"] == 0.1
    preset = config_from_dict({"env": {"preset": "cadrl"}}).env
    assert preset.options.terms.observations == preset.options.terms.rewards == "cadrl"
    assert config_from_dict(config_from_dict({"env": {"preset": "cadrl"}}).to_dict()).env == preset
    # nested options with flat keys on top; the max_agents of a small curriculum is its own
    mixed = config_from_dict({"env": {"curriculum": [[0, 2]], "max_agents": 2, "num_humans": 3,
                                      "options": {"humans": {"num_humans": 1,
                                                             "human_model": "orca"}}}})
    assert mixed.env.options.humans.num_humans == 3
    assert mixed.env.options.humans.human_model == "orca" and mixed.env.slots == 2
    assert mixed.env.options.terms.observations == "navigation"  # the trainer's default


def _checkpoint_with(tmp_path, name, data):
    payload = {"config": yaml.safe_dump(data), "meta": json.dumps({}), "runner": {}}
    path = tmp_path / name
    path.write_bytes(serialization.msgpack_serialize(payload))
    return path


def test_checkpoints_keep_their_world_when_the_default_changes(tmp_path):
    """A saved config states every make option (``arrived``/``ended`` among them) even at its
    default; a checkpoint written before it stated ``arrived`` was trained when the default was
    ``park`` and loads so."""
    config = config_from_dict({"env": {"curriculum": [[0, 2]]}})
    robots = config.to_dict()["env"]["options"]["robots"]
    assert robots["arrived"] == "settle" and robots["ended"] == "leave"
    path = _checkpoint_with(tmp_path, "new.msgpack", config.to_dict())
    assert checkpoint.read(path)[0] == config
    assert checkpoint.training_options(path) == config.env.options
    old = {**config.to_dict(), "env": {"scenarios": ["doorway"], "curriculum": [[0, 2]],
                                       "preset": None, "observations": "navigation"}}
    loaded, _, _ = checkpoint.read(_checkpoint_with(tmp_path, "old.msgpack", old))
    assert loaded.env.options.robots.arrived == "park"
    assert loaded.env.options == config.env.options.replace(arrived="park")


def test_checkpoints_with_flat_make_options_still_load(tmp_path):
    """Files written before the options were nested hold them as flat keys of the env section
    (only those that differ from the defaults, plus the world semantics): they load to the same
    typed options, and their policy acts in them."""
    old = {"env": {"scenarios": ["open"], "curriculum": [[0, 2], [100, 3]], "preset": "cadrl",
                   "arrived": "park", "ended": "leave", "num_arcs": 7, "num_humans": 2,
                   "human_model": "helbing", "time_limit": 20.0, "max_agents": 4,
                   "observations": "cadrl", "rewards": "cadrl"},
           "algorithm": {"num_envs": 8}, "seed": 3, "num_seeds": 1}
    path = _checkpoint_with(tmp_path, "flat.msgpack", old)
    loaded, _, _ = checkpoint.read(path)
    assert loaded.env.slots == 4 and loaded.env.preset == "cadrl" and loaded.seed == 3
    expected = MakeOptions.from_keywords(arrived="park", num_arcs=7, num_humans=2,
                                         human_model="helbing", time_limit=20.0,
                                         observations="cadrl", rewards="cadrl")
    assert loaded.env.options == expected
    assert policy_options(str(path)) == expected  # through the registered loader
    assert config_from_dict(loaded.to_dict()) == loaded  # and written again, nested


@pytest.fixture(scope="module")
def two_seeds():
    """Sixteen seeds (lanes) of a GRU + attention network, and one update of all of them as
    lanes of one function (compiled once for the tests below). Sixteen lanes in one call used
    to hang XLA:CPU (docs/xla-cpu-deadlock.md)."""
    config = tiny(num_seeds=16, env={"observations": "navigation"},
                  network={"kind": "gru", "recurrent_size": 16, "hidden": [16],
                           "others_encoder": "attention", "encoder_size": 8})
    trainer = Trainer(config)
    step = lambda r: trainer.update_chunk(r, 1)  # noqa: E731
    return config, trainer, step, jax.jit(lambda r: trainer.update_chunk_lanes(r, 1))


@pytest.mark.slow
def test_multi_seed_vmap_matches_separate_seeds(two_seeds):
    config, trainer, step, vstep = two_seeds
    keys = seed_keys(config)
    together, _ = vstep(jax.vmap(trainer.init)(keys))
    single = jax.jit(step)
    for i in range(2):
        alone, _ = single(trainer.init(keys[i]))
        mine = jax.tree.map(lambda x, i=i: x[i], together.params)
        # Adam divides each gradient by its own size (eps 1e-5): a near-zero gradient that the
        # batched and the single program round differently moves its weight by a visible part
        # of a step (lr 3e-4). 3e-5 is a tenth of a step; a wrong lane is off by whole steps.
        assert leaves_close(mine, alone.params, rtol=1e-4, atol=3e-5)


@pytest.mark.slow
def test_sequential_and_batched_lanes_train_the_same_seeds():
    """``algorithm.lanes``: the learning phases one lane after another (each a batch of one)
    give every lane what one vmap gives it, up to float rounding; the lanes differ. (A GRU with
    an LSTM encoder: both kinds of carried state in one network; an MLP's lanes:
    test_compact_lanes_train_the_same_seeds_batched_or_sequential.)"""
    network = {"kind": "gru", "recurrent_size": 16, "hidden": [16], "others_encoder": "lstm",
               "encoder_size": 8}
    runs = {}
    for mode in ("batched", "sequential"):
        config = tiny(num_seeds=3, env={"observations": "navigation"}, network=network,
                      algorithm={"lanes": mode})
        trainer = Trainer(config)
        assert trainer.sequential_lanes == (mode == "sequential")
        runner, logs = jax.jit(lambda r, t=trainer: t.update_chunk_lanes(r, 2))(
            jax.vmap(trainer.init)(seed_keys(config)))
        assert logs["policy_loss"].shape == (3, 2)
        runs[mode] = runner, logs
    (batched, b_logs), (sequential, s_logs) = runs["batched"], runs["sequential"]
    assert leaves_close(batched.params, sequential.params, rtol=1e-4, atol=3e-5)
    np.testing.assert_allclose(b_logs["value_loss"], s_logs["value_loss"], rtol=1e-4)
    np.testing.assert_array_equal(b_logs["episodes"], s_logs["episodes"])
    first = jax.tree.leaves(sequential.params)[0]
    assert not np.allclose(first[0], first[1])


@pytest.mark.parametrize("network,levels", [
    ({"hidden": [16]}, None),
    ({"kind": "gru", "recurrent_size": 8, "hidden": [16], "others_encoder": "lstm",
      "encoder_size": 8}, None),
    ({"hidden": [16]}, {"method": "accel", "buffer_size": 4, "min_fill": 0.25}),
], ids=["mlp", "gru_others_lstm", "curriculum"])
def test_a_training_call_returns_the_types_it_takes_so_it_compiles_once(network, levels):
    """The runner after an update has the shapes, dtypes and weak types of the runner ``init``
    made: otherwise the first training call of every command traces and compiles the update
    again for the second (the running statistics' weakly typed start count once did that, and
    a curriculum's level buffer its weakly typed empty scores)."""
    env = {"observations": "navigation"}
    if levels is not None:  # a curriculum picks generated worlds
        env |= {"scenarios": ["generated:doorway"], "curriculum": [[0, 2]], "time_limit": 1.0}
    extra = {} if levels is None else {"levels": levels}
    config = tiny(num_seeds=2, env=env, network=network, **extra)
    trainer = Trainer(config)
    runner = jax.eval_shape(jax.vmap(trainer.init), seed_keys(config))
    after, _ = jax.eval_shape(lambda r: trainer.update_chunk_lanes(r, 1), runner)
    before = jax.tree_util.tree_flatten_with_path(runner)[0]
    changed = [jax.tree_util.keystr(path) for (path, a), b in zip(
        before, jax.tree.leaves(after), strict=True)
        if (a.shape, a.dtype, a.weak_type) != (b.shape, b.dtype, b.weak_type)]
    assert not changed, changed


def test_vmapped_network_init_runs_no_batched_qr(two_seeds):
    """Batched QRs side by side deadlock XLA:CPU (docs/xla-cpu-deadlock.md): a vmapped init
    factorises one matrix at a time."""
    config, trainer, _, _ = two_seeds
    jaxpr = jax.make_jaxpr(jax.vmap(trainer.init))(seed_keys(config)).jaxpr
    qrs = [eqn for eqn in equations(jaxpr) if eqn.primitive.name in ("qr", "geqrf", "geqp3")]
    assert qrs, "expected orthogonal initialisers"
    assert all(v.aval.ndim == 2 for eqn in qrs for v in eqn.invars), [
        [v.aval.shape for v in eqn.invars] for eqn in qrs]


@pytest.mark.slow
def test_checkpoint_round_trip_and_resume_continue_the_same_run(two_seeds, tmp_path):
    config, trainer, _, one = two_seeds
    start = jax.vmap(trainer.init)(seed_keys(config))
    straight, _ = one(one(start)[0])
    half, _ = one(start)
    path = checkpoint.save(tmp_path / "c.msgpack", config, half, {"steps": 1, "updates": 1})
    restored, meta = checkpoint.restore(path, trainer)
    assert meta["updates"] == 1 and leaves_close(restored, half, rtol=0, atol=0)
    resumed, _ = one(restored)
    assert leaves_close(resumed.params, straight.params, rtol=0, atol=0)
    assert not list(tmp_path.glob("*.tmp"))  # written atomically


@pytest.mark.slow
def test_a_checkpoint_policy_loads_from_the_file_alone(two_seeds, tmp_path, monkeypatch):
    """The saved actor acts as Trainer.policy does, without building a Trainer; a checkpoint
    saved before the actor layout was kept in its meta still loads (one environment built)."""
    config, trainer, _, one = two_seeds
    runner, _ = one(jax.vmap(trainer.init)(seed_keys(config)))
    path = checkpoint.save(tmp_path / "c.msgpack", config, runner, {"best_seed": 1},
                           trainer.actor)
    old = checkpoint.save(tmp_path / "old.msgpack", config, runner, {"best_seed": 1})
    env, params = trainer.batch.env, trainer.batch.params[0]
    weights = ActorWeights.of(runner).seed(1)
    expected = trainer.policy(weights.params, weights.obs_stats, True, weights.obs_mask)

    def no_trainer(*args, **kwargs):
        raise AssertionError("loading a checkpoint built a Trainer")

    made = []
    real_make = checkpoint.make
    monkeypatch.setattr(trainer_module.Trainer, "__init__", no_trainer)
    monkeypatch.setattr(checkpoint, "make", lambda *a, **k: made.append(a) or real_make(*a, **k))
    loaded = checkpoint.load_checkpoint_policy(path, env, deterministic=True)
    through_sgjax = load_policy(str(path), env)  # through the registered loader
    assert made == []
    from_old = checkpoint.load_checkpoint_policy(old, deterministic=True)
    assert len(made) == 1  # the others encoder's layout, from one training environment
    assert checkpoint.actor_layout(old, *checkpoint.read(old)) == trainer.actor
    assert policy_options(str(path)) == config.env.options
    with pytest.raises(ValueError, match="seed index 16 out of range"):
        checkpoint.load_checkpoint_policy(path, env, seed_index=16)

    obs, state = env.reset(jax.random.PRNGKey(3), params)
    key = jax.random.PRNGKey(4)
    reference = expected.step(expected.init(2), obs, key, state, params)
    for policy in (loaded, from_old):
        carry, action = policy.step(policy.init(2), obs, key, state, params)
        assert action.tolist() == reference[1].tolist()
        assert np.allclose(carry, reference[0], atol=1e-6)
    assert through_sgjax.step(through_sgjax.init(2), obs, key, state, params)[1].shape == (2,)
    greedy = load_policy(str(path), env, deterministic=True)  # sgjax evaluate --greedy
    assert greedy.step(greedy.init(2), obs, key, state, params)[1].tolist() == (
        reference[1].tolist())


@pytest.mark.slow
def test_mappo_with_lstm_encoder_and_continuous_actions_updates():
    config = tiny(algorithm={"name": "mappo"},
                  network={"others_encoder": "lstm", "encoder_size": 8, "agent_id": True},
                  env={"action_mode": "continuous", "observations": "navigation"})
    trainer = Trainer(config)
    runner = trainer.init(jax.random.PRNGKey(1))
    after, logs = jax.jit(lambda r: trainer.update_chunk(r, 2))(runner)
    assert all(np.isfinite(np.asarray(v)).all() for v in logs.values())
    assert not leaves_close(after.params, runner.params)
    kernel = after.params["params"]["critic"]["Dense_0"]["kernel"]
    assert kernel.shape[0] == trainer.slots * (trainer.batch.obs_size + 1)  # global state + id


SHARED_ENCODER = {"others_encoder": "lstm", "encoder_size": 8, "shared_encoder": True}


@pytest.fixture(scope="module")
def shared_encoder() -> Trainer:
    """A tiny trainer whose one LSTM others encoder feeds both towers (its ``init`` compiled
    once for the tests that use it)."""
    return Trainer(tiny(network=SHARED_ENCODER, env={"observations": "navigation"}))


@pytest.mark.slow
def test_others_encoders_learn_shared_or_separate(shared_encoder):
    """``network.shared_encoder``: one others encoder (parameters ``encoder``) feeds both
    towers and learns (separate encoders learn as well:
    test_compact_learning_phase_matches_the_masked_one[lstm-False])."""
    trainer = shared_encoder
    runner = trainer.init(jax.random.PRNGKey(1))
    params = runner.params["params"]
    assert "encoder" in params
    assert not any("OthersEncoder" in name for name in (*params["actor"], *params["critic"]))
    after, logs = jax.jit(lambda r: trainer.update_chunk(r, 1))(runner)
    assert all(np.isfinite(np.asarray(v)).all() for v in logs.values())
    assert not leaves_close(after.params["params"]["encoder"], params["encoder"])
    separate = Trainer(tiny(network={"others_encoder": "lstm", "encoder_size": 8},
                            env={"observations": "navigation"}))
    count = lambda tree: sum(v.size for v in jax.tree.leaves(tree))  # noqa: E731
    fresh = jax.eval_shape(separate.init, jax.random.PRNGKey(1))
    assert count(fresh.params) - count(runner.params) == count(params["encoder"])


def test_lstm_encoder_skips_the_slots_that_are_always_empty_in_training(shared_encoder):
    """The trainer's LSTM reads only the slots that can hold a body in its environments (one
    other robot here, of k = 4 slots): outputs and gradients equal, bit for bit, those of the
    network reading every slot, which the saved actor keeps for other robot counts."""
    from train.algorithm.networks import ActorCritic, initial_carry

    trainer = shared_encoder
    assert trainer.actor.others.k == 4 and trainer.network.bodies == 1
    every = ActorCritic(trainer.config.network, trainer.actor.action_dim, trainer.actor.discrete,
                        trainer.actor.others)
    runner = trainer.init(jax.random.PRNGKey(3))
    runner, _ = jax.jit(lambda r: jax.lax.scan(
        lambda r, x: rollout.env_step(trainer.rollout_parts, r, x), r, None, 5))(runner)
    actor, critic = trainer.inputs(runner.obs_stats, runner.obs)
    assert float(jnp.abs(actor).sum()) > 0
    carry = initial_carry(trainer.config.network, trainer.num_agents)
    starts = jnp.zeros((1, trainer.num_agents), bool)

    def loss(params, model):
        _, out, value = model.apply(params, carry, actor[None], critic[None], starts)
        return jnp.sum(out ** 2) + jnp.sum(value ** 2)

    for fn in (loss, jax.grad(loss)):
        quick = jax.jit(fn, static_argnums=1)(runner.params, trainer.network)
        full = jax.jit(fn, static_argnums=1)(runner.params, every)
        for a, b in zip(jax.tree.leaves(quick), jax.tree.leaves(full), strict=True):
            np.testing.assert_array_equal(a, b)


def test_masks_and_the_others_encoder_read_the_observation_column_layout():
    """Ablation masks, the others encoder's layout and its slot count come from the
    observation's published column layout (no term internals): ``pose.heading``,
    ``others.<feature>``, or any ``term.feature`` the layout names."""
    import sgjax
    from train.algorithm.env_batch import observation_mask
    from train.algorithm.networks import OthersLayout, most_seen, others_layout

    env, _ = sgjax.make("open", num_agents=2, max_agents=3, observations="socialgym")
    columns = env.config.observer.columns(env.config.layout)
    mask = observation_mask(env, ["pose.heading", "others.velocity", "collision"])
    hidden = [columns.names[i] for i in np.flatnonzero(mask == 0)]
    assert hidden == (["pose.cos_heading", "pose.sin_heading", "collision.collision"]
                      + [f"others.{v}[{i}]" for i in range(6) for v in ("vx", "vy")])
    start = columns.span("others").start
    # socialgym: 6 bodies of position (2), heading (2), velocity (2), mask (1)
    assert others_layout(env) == OthersLayout(start=start, k=6, width=7, mask_column=6)
    assert most_seen(env) == 2  # two other robot slots, no pedestrians
    velocity = observation_mask(env, ["velocity.omega"])
    assert [columns.names[i] for i in np.flatnonzero(velocity == 0)] == [
        "velocity.omega[0]", "velocity.omega[1]"]
    with pytest.raises(ConfigError, match="'pose' has no feature 'theta'; its features are "
                                          "position, heading"):
        observation_mask(env, ["pose.theta"])
    with pytest.raises(ConfigError, match="no observation term 'lidar'"):
        observation_mask(env, ["lidar"])
    bare, _ = sgjax.make("open", num_agents=2, observations="default")
    assert others_layout(bare) is None and most_seen(bare) is None


def test_gru_state_resets_at_episode_starts():
    gru = ResetGRU(4)
    x = jax.random.normal(jax.random.PRNGKey(0), (3, 2, 5))
    params = gru.init(jax.random.PRNGKey(1), jnp.zeros((2, 4)), (x, jnp.zeros((3, 2), bool)))
    carry = jnp.ones((2, 4))
    starts = jnp.asarray([[True, False], [False, False], [False, False]])
    _, ys = gru.apply(params, carry, (x, starts))
    _, fresh = gru.apply(params, jnp.zeros((2, 4)), (x, starts))
    assert np.allclose(ys[:, 0], fresh[:, 0])  # robot 0 was reset at step 0
    assert not np.allclose(ys[:, 1], fresh[:, 1])  # robot 1 kept its memory


def test_lstm_memory_resets_at_episode_starts_and_follows_torchs_lstm():
    """``ResetLSTM`` is torch's ``nn.LSTM`` (sb3-contrib's RecurrentPPO): gates input, forget,
    cell, output from the input and the hidden state, ``c' = f c + i g``, ``h' = o tanh(c')``,
    checked against those equations in numpy; its carry ``[c, h]`` is zeroed at a start."""
    size, features = 4, 5
    lstm = ResetLSTM(size)
    x = jax.random.normal(jax.random.PRNGKey(0), (3, 2, features))
    starts = jnp.asarray([[True, False], [False, False], [False, False]])
    params = lstm.init(jax.random.PRNGKey(1), jnp.zeros((2, 2 * size)), (x, starts))
    carry = jax.random.normal(jax.random.PRNGKey(2), (2, 2 * size))
    out_carry, ys = lstm.apply(params, carry, (x, starts))
    cell = jax.tree.map(np.asarray, params["params"]["LSTMCell_0"])
    sigmoid = lambda v: 1 / (1 + np.exp(-v))  # noqa: E731

    def gate(name, inputs, hidden):
        return inputs @ cell[f"i{name}"]["kernel"] + hidden @ cell[f"h{name}"]["kernel"] + cell[
            f"h{name}"]["bias"]

    c, h = np.asarray(carry[:, :size]), np.asarray(carry[:, size:])
    for t in range(3):
        fresh = np.asarray(starts[t])[:, None]
        c, h = np.where(fresh, 0.0, c), np.where(fresh, 0.0, h)
        xt = np.asarray(x[t])
        i, f = sigmoid(gate("i", xt, h)), sigmoid(gate("f", xt, h))
        g, o = np.tanh(gate("g", xt, h)), sigmoid(gate("o", xt, h))
        c = f * c + i * g
        h = o * np.tanh(c)
        np.testing.assert_allclose(np.asarray(ys[t]), h, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(np.asarray(out_carry), np.concatenate([c, h], -1), rtol=1e-5,
                               atol=1e-6)
    _, fresh_ys = lstm.apply(params, jnp.zeros((2, 2 * size)), (x, starts))
    assert np.allclose(ys[:, 0], fresh_ys[:, 0])  # robot 0 was reset at step 0
    assert not np.allclose(ys[:, 1], fresh_ys[:, 1])  # robot 1 kept its memory


@pytest.mark.slow
def test_an_lstm_ppo_run_trains_and_its_checkpoint_acts(tmp_path):
    """``network.kind: lstm``: the actor and the critic each carry ``[c, h]`` (twice
    ``recurrent_size``), an update runs, and the saved actor acts with its own memory."""
    from sgjax.evaluation.evaluate import policy_environment, run_episodes
    from train.algorithm.networks import carry_size, initial_carry
    from train.run.checkpoint import load_checkpoint_policy, save

    config = tiny(network={"kind": "lstm", "recurrent_size": 8, "hidden": [16]},
                  env={"time_limit": 5.0})
    assert config.network.recurrent and carry_size(config.network) == 16
    assert initial_carry(config.network, 3)[0].shape == (3, 16)
    trainer = Trainer(config)
    assert trainer.learner.recurrent
    runner = trainer.init(jax.random.PRNGKey(0))
    runner, logs = jax.jit(lambda r: trainer.update_chunk(r, 2))(runner)
    assert all(np.all(np.isfinite(np.asarray(v))) for v in jax.tree.leaves(logs))
    lanes = jax.tree.map(lambda x: x[None], runner)
    path = save(tmp_path / "lstm.msgpack", config, lanes, {}, trainer.actor)
    env, by_count = policy_environment("open", [2], None, config.env.options)
    played = run_episodes(env, by_count[2], load_checkpoint_policy(path, env),
                          jax.random.PRNGKey(1), 2)
    assert np.isfinite(np.asarray(played.values["episode_length"])).all()
    with pytest.raises(ValueError, match="kind"):
        config_from_dict({"network": {"kind": "rnn"}})


def test_team_reward_shares_the_mean_of_the_robots_that_acted():
    from train.algorithm.env_batch import share_rewards

    reward = jnp.array([[1.0, 3.0, 100.0], [2.0, 0.0, 0.0]])
    acted = jnp.array([[True, True, False], [True, False, False]])
    np.testing.assert_allclose(share_rewards(reward, acted, 0.0), [[1, 3, 0], [2, 0, 0]])
    np.testing.assert_allclose(share_rewards(reward, acted, 1.0), [[2, 2, 0], [2, 0, 0]])
    np.testing.assert_allclose(share_rewards(reward, acted, 0.5), [[1.5, 2.5, 0], [2, 0, 0]])
    with pytest.raises(ValueError, match="team_reward"):
        config_from_dict({"algorithm": {"team_reward": 1.5}})


# ----------------------------------------------------------------------------- algorithm.compact
COMPACT_NETWORKS = {
    "mlp": {"hidden": [32, 32]},
    "gru": {"kind": "gru", "recurrent_size": 16, "hidden": [16]},
    "lstm": {"others_encoder": "lstm", "encoder_size": 8},
    "lstm_ppo": {"kind": "lstm", "recurrent_size": 8, "hidden": [16]},
}
RECURRENT = ("gru", "lstm_ppo")  # memories over time: minibatches of whole agent sequences


def test_compact_auto_is_on_for_a_cpu_and_off_elsewhere(monkeypatch):
    """The default ``algorithm.compact: auto``: compacted on a CPU (the learning phase 2.3x
    faster there), masked on a GPU (1.6x slower compacted on an H200); true/false win; any
    other value is an error naming the key."""
    assert tiny().algorithm.compact == "auto"
    assert Trainer(tiny()).compact is True
    assert Trainer(tiny(algorithm={"compact": False})).compact is False
    monkeypatch.setattr(trainer_module.jax, "default_backend", lambda: "gpu")
    assert Trainer(tiny()).compact is False
    assert Trainer(tiny(algorithm={"compact": True})).compact is True
    with pytest.raises(ConfigError, match="compact must be true, false or 'auto', got 'yes'"):
        tiny(algorithm={"compact": "yes"})


class CompactRun(NamedTuple):
    """A masked and a compacted trainer of the same tiny run (two robots in three slots: one
    slot is always absent), the fresh run both start from, a rollout of its first update,
    and each trainer's ``learn_lane`` jitted (by ``config.algorithm.compact``)."""

    masked: Trainer
    compact: Trainer
    runner: RunnerState
    rollout: Rollout
    learn: dict[bool, Callable[..., Any]]


def _compact_run(name: str) -> CompactRun:
    """The :class:`CompactRun` of ``COMPACT_NETWORKS[name]``."""
    masked, compact = (Trainer(tiny(env={"observations": "navigation", "max_agents": 3},
                                    network=COMPACT_NETWORKS[name],
                                    algorithm={"compact": flag}))
                       for flag in (False, True))
    runner = masked.init(jax.random.PRNGKey(4))  # compact.init gives the same: one network
    _, rollout, _ = jax.jit(masked.collect)(runner)
    learn = {t.config.algorithm.compact: jax.jit(t.learn_lane) for t in (masked, compact)}
    return CompactRun(masked, compact, runner, rollout, learn)


@pytest.fixture(scope="module")
def compact_runs() -> Callable[[str], CompactRun]:
    """``name -> CompactRun``, each built, rolled out and compiled once for the tests of this
    file (the gradient and learning-phase tests of a network share them)."""
    return functools.cache(_compact_run)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(COMPACT_NETWORKS))
def test_compact_minibatch_gradient_equals_the_masked_one(name, compact_runs):
    """``algorithm.compact``: a minibatch's gradient and loss terms, computed over its active
    units only (transitions; agent sequences for a GRU), are the masked minibatch's, for the
    same minibatch (the same agents); the chunks that hold no active unit are not run."""
    masked, compact, start, rollout, _ = compact_runs(name)
    assert compact.learner.recurrent == (name in RECURRENT)
    # a third of the rest inactive too, at random (as settled or parked robots)
    drop = jax.random.bernoulli(jax.random.PRNGKey(5), 0.33, rollout.traj.active.shape)
    rollout = rollout.replace(traj=rollout.traj.replace(active=rollout.traj.active & ~drop))
    params = start.params
    order = jax.random.permutation(jax.random.PRNGKey(6), compact.num_agents)
    dense = masked.learner.masked_batches(order, rollout)
    units, counts = jax.jit(compact.learner.compact_batches)(order, rollout)
    counts = np.asarray(counts)
    assert counts.min() > 0 and counts.max() < units.shape[1]  # some skipped in every minibatch
    chunk, _ = learning.compact_chunks(units.shape[1])
    if name == "mlp":  # transitions: some minibatch ends in half chunks
        assert any(count % chunk for count in counts)
    dense_grad = jax.jit(jax.grad(masked.learner.loss, has_aux=True))
    compact_grad = jax.jit(compact.learner.compact_grads)
    for j in range(len(counts)):
        grads, aux = dense_grad(params, *jax.tree.map(lambda x, j=j: x[j], dense))
        c_grads, c_aux = compact_grad(params, (units[j], counts[j]), rollout)
        assert leaves_close(c_grads, grads, rtol=1e-4, atol=1e-6), j
        for term in losses.LOSS_TERMS:
            np.testing.assert_allclose(c_aux[term], aux[term], rtol=1e-4, atol=1e-6)
    # the units that can learn come first, and they are the minibatch's active ones
    size = compact.num_agents // compact.config.algorithm.num_minibatches
    for j, count in enumerate(counts):
        first = np.asarray(compact.learner.unit_data(rollout, units[j])[1].active).any(axis=0)
        assert first[:count].all() and not first[count:].any()
        dense_active = np.asarray(dense[1].active[j])  # [T, U]
        assert count == (dense_active.any(axis=0).sum() if name in RECURRENT
                         else dense_active.sum())
    assert units.shape[1] == (size if name in RECURRENT
                              else size * compact.config.algorithm.num_steps)


@pytest.mark.parametrize(("name", "all_active"), [
    *((name, False) for name in COMPACT_NETWORKS), ("mlp", True)])
@pytest.mark.slow
def test_compact_learning_phase_matches_the_masked_one(name, all_active, compact_runs):
    """A whole learning phase (epochs of shuffled minibatches, Adam) gives the masked path's
    parameters and loss terms up to float rounding: with the rollout's own absent slots (every
    network) and with every slot active (nothing to skip; the MLP)."""
    _, _, runner, rollout, learn = compact_runs(name)
    if all_active:
        rollout = rollout.replace(traj=rollout.traj.replace(
            active=jnp.ones_like(rollout.traj.active)))
    key = jax.random.PRNGKey(7)
    out = {compact: fn(runner.params, runner.opt_state, key, rollout)
           for compact, fn in learn.items()}
    (m_params, _, m_key, m_aux), (c_params, _, c_key, c_aux) = out[False], out[True]
    np.testing.assert_array_equal(m_key, c_key)
    assert leaves_close(c_params, m_params, rtol=1e-4, atol=3e-5)
    assert not leaves_close(c_params, runner.params)
    for term in losses.LOSS_TERMS:
        np.testing.assert_allclose(c_aux[term], m_aux[term], rtol=1e-3, atol=1e-6)
    if name == "lstm":
        # Separate others encoders learn: the others' 0/1 mask reaches them unnormalised in
        # the rollout's inputs (normalised, the other robot's always-1 flag became 0 and the
        # encoders saw nobody, never learning).
        for tower in ("actor", "critic"):
            assert not leaves_close(c_params["params"][tower]["OthersEncoder_0"],
                                    runner.params["params"][tower]["OthersEncoder_0"]), tower


@pytest.mark.slow
def test_compact_lanes_train_the_same_seeds_batched_or_sequential():
    """Under ``algorithm.lanes: batched`` (one vmap: the lanes' chunk loops run together, to
    the longest) and ``sequential`` the compacted update gives each seed the masked update's
    parameters, up to float rounding, and the two lane layouts give each other's; the lanes
    differ. (An MLP; a GRU with an LSTM encoder:
    test_sequential_and_batched_lanes_train_the_same_seeds.)"""
    runs = {}
    for compact, lanes in ((False, "batched"), (True, "batched"), (True, "sequential")):
        config = tiny(num_seeds=2, env={"observations": "navigation", "max_agents": 3},
                      network=COMPACT_NETWORKS["mlp"],
                      algorithm={"compact": compact, "lanes": lanes})
        trainer = Trainer(config)
        runs[compact, lanes] = jax.jit(lambda r, t=trainer: t.update_chunk_lanes(r, 2))(
            jax.vmap(trainer.init)(seed_keys(config)))
    reference, logs = runs[False, "batched"]
    for key in ((True, "batched"), (True, "sequential")):
        runner, other = runs[key]
        assert leaves_close(runner.params, reference.params, rtol=1e-4, atol=3e-5), key
        np.testing.assert_array_equal(other["episodes"], logs["episodes"])
        np.testing.assert_allclose(other["value_loss"], logs["value_loss"], rtol=1e-3)
    (batched, b_logs), (sequential, s_logs) = runs[True, "batched"], runs[True, "sequential"]
    assert leaves_close(batched.params, sequential.params, rtol=1e-4, atol=3e-5)
    np.testing.assert_allclose(b_logs["value_loss"], s_logs["value_loss"], rtol=1e-4)
    first = jax.tree.leaves(sequential.params)[0]
    assert not np.allclose(first[0], first[1])


@pytest.mark.parametrize("network", ["shared_encoder", "gru", "mlp"])
def test_critic_alone_gives_the_values_of_the_whole_network(network, shared_encoder,
                                                            compact_runs):
    """``ActorCritic.value`` (the bootstrap values of the rollout) is the whole network's
    value, bit for bit, for separate and shared encoders and a GRU (the trainers of the
    tests above: the GRU's and the MLP's with an absent slot)."""
    from train.algorithm.networks import ActorCritic, initial_carry

    trainer = (shared_encoder if network == "shared_encoder"
               else compact_runs(network).masked)
    runner = trainer.init(jax.random.PRNGKey(2))
    actor, critic = trainer.inputs(runner.obs_stats, runner.obs)
    carry = jax.tree.map(lambda c: c + 0.5, initial_carry(trainer.config.network,
                                                          trainer.num_agents))
    starts = jnp.zeros((1, trainer.num_agents), bool)
    whole = jax.jit(lambda p: trainer.network.apply(p, carry, actor[None], critic[None], starts))
    alone = jax.jit(lambda p: trainer.network.apply(p, carry[1], actor[None], critic[None],
                                                    starts, method=ActorCritic.value))
    (_, critic_carry), _, value = whole(runner.params)
    carry_alone, value_alone = alone(runner.params)
    np.testing.assert_array_equal(value_alone, value)
    np.testing.assert_array_equal(carry_alone, critic_carry)


@pytest.mark.parametrize("network, algorithm", [(COMPACT_NETWORKS["mlp"], "ippo"),
                                                (COMPACT_NETWORKS["gru"], "mappo")])
def test_final_values_come_from_the_truncating_environments_alone(network, algorithm):
    """The rollout's bootstrap values (``train.algorithm.rollout.final_values``): on every robot
    of an environment with a truncated robot, the critic's value of its final observation from the
    step's memory, as one pass over the whole batch gives it (up to float rounding: the
    products are smaller); 0 elsewhere. 40 environments, about half truncating: three chunks
    of 8 (``sgjax.kernels.row_chunks.chunk_size``), the last partly filled. (Under MAPPO the
    critic reads every robot of an environment; a GRU's memory comes along row by row.)"""
    from train.algorithm.networks import initial_carry
    from train.algorithm.normalize import RunningStats

    trainer = Trainer(tiny(network=network, algorithm={"name": algorithm, "num_envs": 40}))
    envs, slots, size = trainer.num_envs, trainer.slots, trainer.batch.obs_size
    keys = jax.random.split(jax.random.PRNGKey(2), 7)
    final = jax.random.normal(keys[0], (envs, slots, size))
    truncated = jax.random.uniform(keys[1], (envs, slots)) < 0.3
    stats = RunningStats(mean=jax.random.normal(keys[2], (size,)),  # not the identity
                         var=jax.random.uniform(keys[3], (size,), minval=0.5, maxval=2.0),
                         count=jnp.asarray(10.0))
    carry = tuple(jax.random.normal(k, c.shape) for k, c in zip(
        keys[4:6], initial_carry(trainer.config.network, envs * slots), strict=True))
    actor, critic = trainer.inputs(stats, final)
    params = trainer.network.init(keys[6], carry, actor[None], critic[None],
                                  jnp.zeros((1, envs * slots), bool))
    mask = jnp.ones(size)
    parts = trainer.rollout_parts
    values = jax.jit(functools.partial(rollout.final_values, parts))(
        params, carry, stats, final, mask, truncated)
    every = jax.jit(functools.partial(rollout.critic_value, parts))(
        params, carry, actor, critic, jnp.zeros(envs * slots, bool))
    ending_envs = np.asarray(jnp.any(truncated, axis=1))
    assert 16 < ending_envs.sum() < 24, ending_envs.sum()  # 3 chunks of 8, the last partly
    ending = np.repeat(ending_envs, slots)
    np.testing.assert_allclose(values[ending], every[ending], rtol=1e-5, atol=1e-6)
    np.testing.assert_array_equal(values[~ending], 0.0)
    assert not np.allclose(every[~ending], 0.0)  # the test can tell a value from a zero


@pytest.mark.slow
def test_a_tiny_compacted_run_learns_with_absent_slots():
    """``algorithm.compact`` trains, as the masked path does: one robot in two slots (half the
    slots never active), continuous actions in the open; success rises from near zero along
    the masked run's curve (the same run up to float rounding)."""
    curves = {}
    for compact in (False, True):
        config = tiny(env={"curriculum": [[0, 1]], "max_agents": 2,
                           "action_mode": "continuous", "time_limit": 20.0,
                           "observations": "default"},
                      algorithm={"num_envs": 64, "num_steps": 32, "total_steps": 64 * 32 * 60,
                                 "learning_rate": 1e-3, "ent_coef": 0.0, "update_epochs": 4,
                                 "num_minibatches": 4, "compact": compact})
        trainer = Trainer(config)
        chunk = jax.jit(lambda r, t=trainer: t.update_chunk(r, 15))
        runner = trainer.init(jax.random.PRNGKey(0))
        rates = []
        for _ in range(4):
            runner, logs = chunk(runner)
            rates.append(float(logs["robot_successes"].sum() / max(logs["robots"].sum(), 1)))
        curves[compact] = rates
    rates = curves[True]
    assert rates[0] < 0.35 and rates[-1] > 0.7, rates  # 0.16 -> 0.76 on 2026-11-26
    assert curves[False][-1] > 0.7, curves[False]  # 0.16 -> 0.82
    # The same run while the rounding differences are small (the first 30 updates: equal to
    # 3 decimals); after that the two runs drift apart as any two rounding orders of one
    # training run do (0.53/0.76 against 0.51/0.82 at 45 and 60 updates on 2026-11-26).
    np.testing.assert_allclose(rates[:2], curves[False][:2], atol=0.01)


def test_active_first_is_a_stable_partition():
    mask = jax.random.bernoulli(jax.random.PRNGKey(0), 0.4, (3, 50))
    mask = mask.at[0].set(True).at[1].set(False)
    np.testing.assert_array_equal(learning.active_first(mask),
                                  jnp.argsort(~mask, axis=-1, stable=True))


def test_long_runs_checkpoint_about_the_number_of_times_asked():
    """train.reproduce and train.ablation train in equal calls (a divisor of the update
    count) and save about ten times: 122 updates in calls of 2 save 10 times, the last at the
    end; a run shorter than ten updates saves after every call."""
    due = [done for done in range(2, 123, 2) if checkpoint.checkpoint_due(done, 2, 122, 10)]
    assert len(due) == 10 and due[-1] == 122
    assert all(b - a <= 14 for a, b in zip([0, *due], due, strict=False))  # at most 13 + 1 lost
    assert [d for d in range(1, 5) if checkpoint.checkpoint_due(d, 1, 4, 10)] == [1, 2, 3, 4]
    assert [d for d in (61, 122) if checkpoint.checkpoint_due(d, 61, 122, 10)] == [61, 122]


@pytest.mark.slow
def test_the_play_modes_program_plays_each_mode_as_its_own_evaluator():
    """train.reproduce's one program for both play modes (the modes as lanes beside the seeds)
    gives ``[modes, seeds, episodes]`` values, each mode's those of the evaluator compiled for
    that mode alone."""
    from sgjax.evaluation.trained import TrainedEvaluation

    config = tiny(num_seeds=2, env={"time_limit": 6.0})
    trainer = Trainer(config)
    weights = ActorWeights.of(jax.vmap(trainer.init)(seed_keys(config)))
    key, modes = jax.random.key(4), (True, False)

    def evaluation(modes):
        return TrainedEvaluation(trainer.trained_actor, "open", [2], 3, config.env.options,
                                 max_agents=trainer.slots, modes=modes)

    both, both_robot = evaluation(modes).lanes(weights, key, 2)
    assert both["success"].shape == (2, 2, 3)
    for index, mode in enumerate(modes):
        alone, alone_robot = evaluation(mode).lanes(weights, key, 2)
        for ours, theirs in ((both, alone), (both_robot, alone_robot)):
            assert ours.keys() == theirs.keys()
            for name in theirs:
                np.testing.assert_allclose(np.asarray(ours[name][index]), np.asarray(theirs[name]),
                                           rtol=1e-6, atol=0, err_msg=f"{mode}: {name}")


def test_a_traced_play_mode_acts_as_the_static_one_under_vmap():
    """train.reproduce's evaluation (sgjax.evaluation.trained.TrainedEvaluation) plays greedy and
    sampled as a vmap over a traced flag, one compilation: under that vmap each mode's actions equal
    the static mode's, bit for bit (MLP and GRU; GO/STOP and continuous)."""
    from train.algorithm.actor import acting_policy

    for network, mode in (({"hidden": [32]}, "go_stop"),
                          ({"kind": "gru", "hidden": [32]}, "continuous")):
        config = tiny(network=network, env={"action_mode": mode})
        trainer = Trainer(config)
        weights = ActorWeights.of(trainer.init(jax.random.key(0)))
        obs = jax.random.normal(jax.random.key(1), (3, trainer.actor.obs_size))
        key = jax.random.key(2)

        def act(flag, weights=weights, obs=obs, key=key, net=config.network,
                layout=trainer.actor):
            policy = acting_policy(net, layout, weights, flag)
            return policy.step(policy.init(3), obs, key, None, None)

        both = jax.jit(jax.vmap(act))(jnp.asarray([False, True]))
        for index, flag in enumerate((False, True)):
            alone = jax.jit(functools.partial(act, flag))()
            for ours, theirs in zip(jax.tree.leaves(both), jax.tree.leaves(alone), strict=True):
                np.testing.assert_array_equal(np.asarray(ours[index]), np.asarray(theirs))
