"""Presets and term configuration through ``sgjax.make``: every preset on every map, YAML files,
clear errors, and the environment contract (jit = eager, vmap = loop, no retrace,
determinism) with the richest terms switched on."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.environment.presets import OBSERVATION_PRESETS, REWARD_PRESETS
from sgjax.terms.base import ConfigError
from sgjax.terms.contract import TermInput

RICH = {
    "observations": ["pose", {"velocity": {"history": 2}}, {"goal_distance": {"history": 2}},
                     "waypoint", {"others": {"k": 3, "line_of_sight": True}},
                     {"lidar": {"beams": 8, "noise": 0.01}}, "zone_priority", "zone_order",
                     "in_zone", "entering_zone"],
    "rewards": {"existence": 1.0, "success": 100.0, "collision": 10.0, "progress": 1.0,
                "proximity": 10.0, "personal_space": 1.0, "velocity_change": 0.1,
                "social_norm_pass": 1.0, "social_norm_overtake": 1.0,
                "social_norm_cross": 1.0, "zone_order": 25.0},
    "enders": ["time_limit", {"stuck": {"steps": 20, "penalty": -10.0}}],
}


@pytest.mark.slow
@pytest.mark.parametrize("scenario, preset", [
    *[(name, "enforced_order") for name in sgjax.registered()],
    *[("doorway", name) for name in ("socialgym", "cadrl", "any_order")],
])
def test_paper_presets_build_and_step(scenario, preset):
    env, params = sgjax.make(scenario, num_agents=3, reward_preset=preset,
                             observation_preset=preset)
    obs, state = env.reset(jax.random.key(0), params)
    assert obs.shape == (3, env.observation_size)
    obs, state, reward, _, _, info = jax.jit(env.step)(jax.random.key(1), state,
                                                       jnp.zeros(3, jnp.int32), params)
    assert set(info["reward_terms"]) >= set(env.config.rewarder.names)
    assert np.isfinite(np.asarray(obs)).all() and np.isfinite(np.asarray(reward)).all()


def test_preset_contents():
    env, _ = sgjax.make("doorway", num_agents=3, reward_preset="enforced_order",
                        observation_preset="enforced_order")
    assert env.config.rewarder.names == ("existence", "success", "collision", "progress",
                                         "zone_order")
    assert env.config.enders.names == ("success", "time_limit", "stuck")
    zone = env.config.rewarder.terms[-1]
    assert not zone.any_order and zone.incorrect_penalty
    slices = env.observation_slices()
    # goal distance x2, goal 2, pose 4, velocity 2 x 3, collision 1, others 6 x 7, zones 7
    assert env.observation_size == 2 + 2 + 4 + 6 + 1 + 42 + 7
    assert slices["zone_exiting_count"] == slice(env.observation_size - 1, env.observation_size)
    ao, _ = sgjax.make("doorway", reward_preset="any_order")
    assert ao.config.rewarder.terms[-1].any_order
    cadrl, _ = sgjax.make("doorway", reward_preset="cadrl")
    assert "proximity" in cadrl.config.rewarder.names
    default, params = sgjax.make("doorway")
    assert default.observation_size == 10
    assert default.config.rewarder.names == ("progress", "success", "collision")
    assert default.config.enders.names == ("success", "time_limit")
    assert set(OBSERVATION_PRESETS) >= set(REWARD_PRESETS) - {"default"}


def test_terms_from_yaml_file(tmp_path):
    path = tmp_path / "terms.yaml"
    path.write_text(
        "observations:\n"
        "  - pose: {heading: false}\n"
        "  - goal\n"
        "  - others: {k: 2, features: [position, mask]}\n"
        "rewards:\n"
        "  success: 50\n"
        "  collision: {weight: 5, per_step: true}\n"
        "  existence: {schedule: linear, start: 0.0, end: 1.0, steps: 1000}\n"
        "enders:\n"
        "  - time_limit\n"
        "  - collision: {scope: robot}\n"
    )
    env, params = sgjax.make("hallway", num_agents=2, terms=path)
    assert env.observation_size == 2 + 2 + 2 * 3
    assert env.config.rewarder.names == ("success", "collision", "existence")
    assert env.config.enders.names == ("success", "time_limit", "collision")
    assert float(params.reward.weights["existence"](500)) == pytest.approx(0.5)
    # One section from a file, the rest by name.
    env2, _ = sgjax.make("hallway", num_agents=2, observations=str(path), reward_preset="cadrl")
    assert env2.observation_size == env.observation_size
    assert "proximity" in env2.config.rewarder.names


def test_make_term_errors(tmp_path):
    with pytest.raises(ConfigError, match="unknown preset 'enforced'.*enforced_order"):
        sgjax.make("doorway", reward_preset="enforced")
    with pytest.raises(ConfigError, match="valid presets are: .*cadrl"):
        sgjax.make("doorway", observation_preset="nope")
    with pytest.raises(ValueError, match="not both"):
        sgjax.make("doorway", rewards="cadrl", reward_preset="cadrl")
    bad = tmp_path / "bad.yaml"
    bad.write_text("rewardz:\n  success: 1\n")
    with pytest.raises(ConfigError, match=r"bad.yaml: unknown section 'rewardz'.*rewards"):
        sgjax.make("doorway", terms=bad)
    with pytest.raises(ConfigError, match="no such file"):
        sgjax.make("doorway", terms=tmp_path / "missing.yaml")
    with pytest.raises(ConfigError, match="given twice"):
        sgjax.make("doorway", terms={"rewards": {"success": 1}}, rewards={"success": 2})
    with pytest.raises(ConfigError, match=r"rewards\.progress: unknown option 'clamp'"):
        sgjax.make("doorway", rewards={"progress": {"clamp": [0, 1]}})


@pytest.fixture(scope="module")
def rich():
    return sgjax.make("intersection", num_agents=3, max_agents=4, num_humans=3, max_humans=4,
                      terms=RICH)


@pytest.mark.slow
def test_rich_terms_jit_equals_eager_and_deterministic(rich):
    """Every rich term (enders, rewards, observations) on a step's states, op by op and
    compiled; the compiled step twice gives the same bits. (The step's own physics and
    bookkeeping, op by op: tests/environment/test_env.py::test_jit_equals_eager; running them
    eagerly here too, with pedestrians, tripled this test's time.)"""
    env, params = rich
    _, state = env.reset(jax.random.key(3), params)
    actions = jnp.asarray([0, 1, 0, 0], jnp.int32)
    step = env.step  # its compiled entry point (shared with the vmap test's single steps)
    jitted = step(jax.random.key(4), state, actions, params)
    again = step(jax.random.key(4), state, actions, params)
    for b, c in zip(jax.tree.leaves(jitted), jax.tree.leaves(again), strict=True):
        np.testing.assert_array_equal(np.asarray(b), np.asarray(c))

    def terms(prev, now):
        inputs = TermInput(prev=prev, state=now, actions=actions, params=params,
                           key=jax.random.key(5), layout=env.config.layout)
        return (env.config.enders(inputs), env.config.rewarder(inputs),
                env.observe(now, params, jax.random.key(6)))

    compiled = jax.jit(terms)(state, jitted[1])
    with jax.disable_jit():
        eager = terms(state, jitted[1])
    for a, b in zip(jax.tree.leaves(eager), jax.tree.leaves(compiled), strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-5, atol=1e-5)


@pytest.mark.slow
def test_rich_terms_vmap_equals_loop_and_no_retrace(rich):
    env, params = rich
    keys = jax.random.split(jax.random.key(5), 3)
    obs, states = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    actions = jnp.zeros((3, 4), jnp.int32)
    traces = []

    def counted(k, s, a, p):
        traces.append(1)
        return env.step(k, s, a, p)

    vstep = jax.jit(jax.vmap(counted, in_axes=(0, 0, 0, None)))
    batched = vstep(keys, states, actions, params)
    for i in range(3):
        single = env.step(keys[i], jax.tree.map(lambda x, i=i: x[i], states), actions[i], params)
        np.testing.assert_allclose(np.asarray(batched[0][i]), np.asarray(single[0]), atol=1e-4)
        np.testing.assert_allclose(np.asarray(batched[2][i]), np.asarray(single[2]), atol=1e-4)
    # New robot and pedestrian counts, new weights: the same compiled step.
    fewer = params.replace(num_agents=jnp.asarray(2, jnp.int32),
                           reward=params.reward.replace(weights={
                               **params.reward.weights,
                               "success": sgjax.rewards.constant(5.0)}))
    fewer = fewer.replace(humans=fewer.humans.replace(num_humans=jnp.asarray(1, jnp.int32)))
    obs, states = jax.vmap(env.reset, in_axes=(0, None))(keys, fewer)
    vstep(keys, states, actions, fewer)
    assert len(traces) == 1


@pytest.mark.slow
def test_rich_terms_long_rollout_stays_finite(rich):
    env, params = rich

    def body(carry, key):
        state, total = carry
        k_act, k_step = jax.random.split(key)
        actions = (jax.random.uniform(k_act, (4,)) < 0.3).astype(jnp.int32)
        obs, state, reward, _, _, info = env.step(k_step, state, actions, params)
        ok = jnp.all(jnp.isfinite(obs)) & jnp.all(jnp.isfinite(reward))
        return (state, total + reward), ok

    _, state = env.reset(jax.random.key(7), params)
    (_, total), ok = jax.jit(lambda s: jax.lax.scan(body, (s, jnp.zeros(4)),
                                                    jax.random.split(jax.random.key(8), 600))
                             )(state)
    assert bool(ok.all()) and np.isfinite(np.asarray(total)).all()


@pytest.mark.slow
def test_docs_terms_examples_run(tmp_path, monkeypatch):
    """The Python and YAML examples of docs/terms.md work as written, in order (the terms the
    "Writing a term" example registers are forgotten afterwards)."""
    import re
    from pathlib import Path

    from sgjax.observations import OBSERVATIONS
    from sgjax.rewards import REWARDS
    from sgjax.terms.enders import ENDERS

    for registry in (OBSERVATIONS, REWARDS, ENDERS):
        monkeypatch.setattr(registry, "classes", dict(registry.classes))
    text = (Path(__file__).resolve().parents[2] / "docs" / "terms.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert len(blocks) == 3
    namespace: dict = {}
    for python in blocks:
        exec(compile(python, "docs/terms.md", "exec"), namespace)
    assert {"speed", "standing", "astray"} <= {*OBSERVATIONS.classes, *REWARDS.classes,
                                               *ENDERS.classes}
    assert namespace["columns"]["others"].offset("mask") == 9
    yaml_text = re.search(r"```yaml\n(.*?)```", text, re.S).group(1)
    path = tmp_path / "my_terms.yaml"
    path.write_text(yaml_text)
    env, _ = sgjax.make("hallway", terms=path)
    assert env.config.enders.names == ("success", "time_limit", "collision")
