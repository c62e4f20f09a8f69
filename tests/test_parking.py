"""World semantics of finished robots: ``arrived="park"`` keeps an arrived robot in the world as
a static body (SocialGym 2.0's behaviour), ``"leave"`` takes it out; ``ended`` does the same for
robots an ender stops."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scenes import go_run_counting_traces, make_room, place

from sgjax.queries import FAR, body_gaps

STEPS = 60


def _drive_through(arrived, ended="leave", enders=None):
    """Robot 0 sits 0.1 m from its goal at the room's centre (it arrives on the first step and
    then holds still); robot 1 drives straight at it from 3 m away at full speed. Returns the
    states of every step."""
    kw = {"enders": enders} if enders is not None else {}
    env, params = make_room(num_agents=2, action_mode="continuous", arrived=arrived,
                            ended=ended, **kw)
    state = place(env, params, [-0.1, -3.0], [0.0, 0.0], starts=[0, 0], goals=[4, 1])
    actions = jnp.array([[0.0, 0.0], [1.0, 0.0]])
    step = jax.jit(env.step_env)
    states = []
    for _ in range(STEPS):
        _, state, *_ = step(jax.random.key(0), state, actions, params)
        states.append(state)
    return env, params, states


def test_a_parked_robot_is_a_body_that_others_meet():
    env, params, states = _drive_through("park")
    last = states[-1]
    assert bool(last.robots.succeeded[0]) and bool(last.robots.parked[0])
    radii = float(params.robots.radius[0] + params.robots.radius[1])
    gaps = [float(jnp.hypot(s.robots.x[1] - s.robots.x[0], s.robots.y[1] - s.robots.y[0]))
            for s in states]
    assert min(gaps) > radii - 0.02, min(gaps)  # it cannot drive through
    # It stays where it parked, and the collision is the driving robot's.
    assert abs(float(last.robots.x[0]) + 0.1) < 1e-6 and float(last.robots.y[0]) == 0.0
    assert int(last.collisions.robot[1]) >= 1 and int(last.collisions.robot[0]) == 0
    # Others observe it: a body gap, and a row in the "others" observation.
    gap = body_gaps(last, params, env.config.layout)[1, 0]
    assert float(gap) < 0.05
    env_obs, params_obs = make_room(num_agents=2, action_mode="continuous",
                                    observations=[{"others": {"k": 1, "humans": False}}])
    seen = env_obs.observe(last, params_obs)
    assert np.any(np.asarray(seen[1]) != 0.0)


def test_leave_takes_an_arrived_robot_out_of_the_world():
    env, params, states = _drive_through("leave")
    last = states[-1]
    assert bool(last.robots.succeeded[0]) and not bool(last.robots.parked[0])
    assert float(last.robots.x[1]) > 1.0  # drove straight through where it was
    assert int(last.collisions.robot[1]) == 0
    assert float(body_gaps(last, params, env.config.layout)[1, 0]) == FAR


def test_leave_is_the_world_without_the_finished_robot():
    """Under ``leave`` the robot that drives on moves exactly as if the arrived one were never
    there (the behaviour before parking existed)."""
    _, _, states = _drive_through("leave")
    env, params = make_room(num_agents=2, action_mode="continuous", arrived="leave")
    alone = place(env, params, [30.0, -3.0], [30.0, 0.0], starts=[0, 0], goals=[4, 1])
    alone = alone.replace(robots=alone.robots.replace(present=jnp.array([False, True])))
    step = jax.jit(env.step_env)
    for with_other in states:
        _, alone, *_ = step(jax.random.key(0), alone, jnp.array([[0.0, 0.0], [1.0, 0.0]]), params)
        for field in ("x", "y"):
            assert float(getattr(with_other.robots, field)[1]) == float(
                getattr(alone.robots, field)[1])


@pytest.mark.parametrize("ended", ["park", "leave"])
def test_a_robot_stopped_by_a_collision_ender_parks_or_leaves(ended):
    """Robot 1 hits a wall and the per-robot collision ender stops it; with ``ended="park"`` it
    stays where it stopped as a body."""
    env, params = make_room(num_agents=2, action_mode="continuous", ended=ended,
                            enders=["success", "time_limit", {"collision": {"scope": "robot"}}])
    state = place(env, params, [0.0, 4.6], [-3.0, 0.0], headings=[0.0, 0.0], starts=[0, 0],
                  goals=[1, 1])
    step = jax.jit(env.step_env)
    actions = jnp.array([[0.0, 0.0], [1.0, 0.0]])
    for _ in range(10):
        _, state, *_ = step(jax.random.key(0), state, actions, params)
    assert bool(state.robots.ended[1])
    assert bool(state.robots.parked[1]) == (ended == "park")
    assert bool(state.robots.in_world[1]) == (ended == "park")


def test_parking_does_not_retrace_across_episodes():
    """Robots park and the episode auto-resets inside one compiled step."""
    env, params = make_room(num_agents=2, arrived="park", time_limit=8.0)
    visited, traces = go_run_counting_traces(env, params, 200)
    assert any(bool(jnp.any(state.robots.parked)) for state, _ in visited)
    assert any(bool(info["episode_done"]) for _, info in visited) and traces == 1


def test_world_semantics_are_validated():
    with pytest.raises(ValueError, match="arrived must be one of"):
        make_room(arrived="stay")
    with pytest.raises(ValueError, match="ended must be one of"):
        make_room(ended="vanish")
