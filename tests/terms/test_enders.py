"""Episode enders alone on hand-built states, and through the environment's step."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scenes import make_room, place

from sgjax.terms.base import ConfigError
from sgjax.terms.contract import TermInput
from sgjax.terms.enders import ENDERS, Enders


def outcome(spec, env, params, prev, state):
    name, options = (spec, {}) if isinstance(spec, str) else next(iter(spec.items()))
    inputs = TermInput(prev=prev, state=state, actions=jnp.zeros(env.max_agents, jnp.int32),
                       params=params, key=jax.random.key(0), layout=env.config.layout)
    return ENDERS.build("test", name, options)(inputs)


@pytest.fixture(scope="module")
def room():
    return make_room(num_agents=3, max_agents=3)


def test_success_terminates_arrivals(room):
    env, params = room
    prev = place(env, params, [0.0, 1.0, 2.0], [0.0, 0.0, 0.0])
    state = prev.replace(robots=prev.robots.replace(succeeded=jnp.asarray([False, True, False])))
    out = outcome("success", env, params, prev, state)
    np.testing.assert_array_equal(out.terminated, [False, True, False])
    assert not bool(out.truncated.any())


def test_time_limit_truncates_at_max_steps(room):
    env, params = room
    prev = place(env, params, [0.0, 1.0, 2.0], [0.0, 0.0, 0.0])
    before = prev.replace(time=params.max_steps - 1)
    at = prev.replace(time=params.max_steps)
    assert not bool(outcome("time_limit", env, params, prev, before).truncated.any())
    assert bool(outcome("time_limit", env, params, prev, at).truncated.all())


def test_stuck_detector_window_distance_and_penalty(room):
    env, params = make_room(num_agents=3, max_agents=3,
                            enders=[{"stuck": {"distance": 0.5, "steps": 4, "penalty": -7.0}}])
    prev = place(env, params, [0.0, 1.0, 2.0], [0.0, 0.0, 0.0])
    assert prev.moved.shape == (4, 3)
    spec = {"stuck": {"distance": 0.5, "steps": 4, "penalty": -7.0}}
    # 0.1 m per step each: 0.4 m over 4 steps < 0.5 m: stuck, once the window is full.
    slow = prev.replace(moved=jnp.full((4, 3), 0.1), time=jnp.asarray(4, jnp.int32))
    out = outcome(spec, env, params, prev, slow)
    np.testing.assert_array_equal(out.truncated, [True, True, True])
    np.testing.assert_allclose(out.reward, [-7, -7, -7])
    early = slow.replace(time=jnp.asarray(3, jnp.int32))
    assert not bool(outcome(spec, env, params, prev, early).truncated.any())
    # One robot travelling 0.6 m keeps the episode going.
    moving = slow.replace(moved=slow.moved.at[:, 2].set(0.15))
    assert not bool(outcome(spec, env, params, prev, moving).truncated.any())
    # A robot that arrived does not count and is not penalised.
    arrived = slow.replace(robots=slow.robots.replace(succeeded=jnp.asarray([False, False,
                                                                              True])),
                           moved=moving.moved)
    out = outcome(spec, env, params, prev, arrived)
    np.testing.assert_array_equal(out.truncated, [True, True, False])
    np.testing.assert_allclose(out.reward, [-7, -7, 0])


@pytest.mark.slow
def test_stuck_through_the_step_all_robots_stopped():
    env, params = make_room(num_agents=2, rewards={"existence": 1.0}, enders=[
        "time_limit", {"stuck": {"distance": 0.5, "steps": 10, "penalty": -100.0}}])
    _, state = env.reset(jax.random.key(0), params)
    stop = jnp.ones(2, jnp.int32)
    step = jax.jit(env.step_env)
    for t in range(10):
        _, state, reward, term, trunc, info = step(jax.random.key(t), state, stop, params)
        if t < 9:
            assert not bool(trunc.any())
    np.testing.assert_array_equal(trunc, [True, True])
    assert not bool(term.any())
    np.testing.assert_allclose(reward, [-101, -101])
    np.testing.assert_allclose(info["reward_terms"]["stuck"], [-100, -100])


def test_collision_ender_team_and_robot(room):
    env, params = room
    prev = place(env, params, [0.0, 1.0, 2.0], [0.0, 0.0, 0.0])
    hit = prev.replace(touching_robot=jnp.asarray([True, False, False]))
    team = outcome("collision", env, params, prev, hit)
    np.testing.assert_array_equal(team.terminated, [True, True, True])
    alone = outcome({"collision": {"scope": "robot"}}, env, params, prev, hit)
    np.testing.assert_array_equal(alone.terminated, [True, False, False])
    walls_only = outcome({"collision": {"robots": False}}, env, params, prev, hit)
    assert not bool(walls_only.terminated.any())
    # An ongoing contact is not a new collision.
    assert not bool(outcome("collision", env, params, hit, hit).terminated.any())


@pytest.mark.slow
def test_collision_ended_robot_leaves_the_world():
    env, params = make_room(num_agents=2, enders=[{"collision": {"scope": "robot"}}])
    r = float(params.robots.radius[0])
    # Two standing robots overlapping: the step reports the contact and ends both episodes.
    state = place(env, params, [0.0, 2 * r - 0.05], [0.0, 0.0], starts=[0, 1], goals=[1, 0])
    _, after, _, term, trunc, _ = env.step_env(jax.random.key(0), state,
                                               jnp.ones(2, jnp.int32), params)
    np.testing.assert_array_equal(term, [True, True])
    assert bool(after.robots.ended.all()) and not bool(after.robots.active.any())
    assert not bool(after.robots.succeeded.any())


def test_ender_config():
    enders = Enders.parse(["time_limit"])
    assert enders.names == ("success", "time_limit")  # success is always there
    assert Enders.parse({"stuck": {"steps": 50}}).window == 50
    with pytest.raises(ConfigError, match="unknown episode ender 'stuk'.*did you mean 'stuck'"):
        Enders.parse(["stuk"])
    with pytest.raises(ConfigError, match="scope must be one of"):
        Enders.parse([{"collision": {"scope": "everyone"}}])
    with pytest.raises(ConfigError, match="repeated"):
        Enders.parse(["time_limit", "time_limit"])
    assert Enders.parse({"stuck": True}).names == ("success", "stuck")
    with pytest.raises(ConfigError, match="expected a list or mapping of episode enders.*stuck"):
        Enders.parse("stuck")
