"""World semantics of finished robots: ``arrived="park"`` keeps an arrived robot in the world as
a static body where it arrived, ``"settle"`` lets its planner drive it on to its goal point and
parks it there (SocialGym 2.0's behaviour), ``"leave"`` takes it out; ``ended`` parks or takes
out robots an ender stops."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scenes import go_run_counting_traces, make_room, place

from sgjax.environment.env import SETTLE_SECONDS, SETTLE_TOLERANCE
from sgjax.terms.queries import FAR, body_gaps

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


def _arrive_short(arrived, action_mode="go_stop", steps=STEPS, heading=0.0):
    """One robot 0.45 m short of its goal (the room's centre, inside the 0.5 m tolerance), at
    rest and facing ``heading`` (rad; 0 faces the goal); it is told to STOP (or stand still)
    at every step. Returns every step's ``(state, reward, terminated, info)``."""
    env, params = make_room(num_agents=1, max_agents=1, arrived=arrived,
                            action_mode=action_mode)
    state = place(env, params, [-0.45], [0.0], headings=[heading], starts=[0], goals=[4])
    stop = jnp.zeros((1, 2)) if action_mode == "continuous" else jnp.ones(1, jnp.int32)
    step = jax.jit(env.step_env)
    out = []
    for _ in range(steps):
        _, state, reward, terminated, _, info = step(jax.random.key(0), state, stop, params)
        out.append((state, reward, terminated, info))
    return out


@pytest.mark.parametrize("action_mode,heading", [("go_stop", 0.0), ("continuous", 0.0),
                                                  ("go_stop", 2.5), ("continuous", 2.5),
                                                  ("continuous", -np.pi / 2)])
def test_a_settling_robot_is_driven_on_to_its_goal_point_and_parks(action_mode, heading):
    """Under ``settle`` the robot arrives (terminated, rewarded) on the first step, then its
    planner (under continuous actions the straight approach), not its actions, drives it to
    within ``SETTLE_TOLERANCE`` of the goal point, facing it or turned away, where it parks; it
    earns nothing on the way and is a moving body meanwhile."""
    steps = _arrive_short("settle", action_mode, heading=heading)
    first_state, first_reward, first_terminated, _ = steps[0]
    assert bool(first_state.robots.succeeded[0]) and bool(first_terminated[0])
    assert float(first_reward[0]) > 0.0  # the arrival bonus
    moving = [s for s, *_ in steps if bool(s.robots.settling[0])]
    assert moving, "it never settled"
    assert all(bool(s.robots.in_world[0]) and not bool(s.robots.active[0]) for s in moving)
    assert any(float(jnp.abs(s.robots.body_velocity[0]).sum()) > 0.05 for s in moving)
    for _, reward, terminated, info in steps[1:]:
        assert float(reward[0]) == 0.0 and not bool(info["was_active"][0])
        assert bool(terminated[0])
    last = steps[-1][0]
    assert bool(last.robots.parked[0]) and not bool(last.robots.settling[0])
    assert float(jnp.hypot(last.robots.x[0], last.robots.y[0])) < SETTLE_TOLERANCE
    assert float(jnp.abs(last.robots.body_velocity[0]).sum()) == 0.0


def test_park_stops_where_it_arrived():
    """The same start under ``park``: the robot stays 0.45 m short, never settling."""
    steps = _arrive_short("park")
    assert not any(bool(s.robots.settling[0]) for s, *_ in steps)
    last = steps[-1][0]
    assert bool(last.robots.parked[0])
    assert float(last.robots.x[0]) == pytest.approx(-0.45, abs=1e-6)


def test_a_settling_robot_is_a_body_that_others_meet_and_see():
    """Robot 0 arrives 0.45 m short of the room's centre facing away from it, so it settles
    slowly (it turns in place first); robot 1 drives up at it from 1.2 m below (continuous
    actions). While robot 0 is still settling, robot 1 touches it (and is stopped short of
    overlapping it) and sees it in its ``others`` observation, moving."""
    env, params = make_room(num_agents=2, action_mode="continuous", arrived="settle",
                            observations=[{"others": {"k": 1, "humans": False}}])
    state = place(env, params, [-0.45, -0.45], [0.0, -1.2], headings=[np.pi, np.pi / 2],
                  starts=[0, 0], goals=[4, 1])
    actions = jnp.array([[0.0, 0.0], [0.6, 0.0]])
    step = jax.jit(env.step_env)
    radii = float(params.robots.radius[0] + params.robots.radius[1])
    met_settling, seen_moving = False, False
    for _ in range(STEPS):
        obs, state, *_ = step(jax.random.key(0), state, actions, params)
        gap = float(jnp.hypot(state.robots.x[1] - state.robots.x[0],
                              state.robots.y[1] - state.robots.y[0]))
        assert gap > radii - 0.02, gap  # it cannot drive through
        if bool(state.robots.settling[0]):
            met_settling |= bool(state.touching_robot[1])
            row = np.asarray(obs[1])  # position, distance, heading, velocity, radius, kind, mask
            seen_moving |= row[-1] == 1.0 and float(np.abs(row[5:7]).sum()) > 0.0
    assert met_settling and seen_moving


def test_a_settling_robot_whose_goal_is_taken_parks_after_settle_seconds():
    """Robot 1 stands (told to STOP) on robot 0's goal point; robot 0 arrives 0.45 m short of
    it and cannot get within ``SETTLE_TOLERANCE``: it parks after ``SETTLE_SECONDS``."""
    env, params = make_room(num_agents=2, arrived="settle")
    state = place(env, params, [-0.45, 0.0], [0.0, 0.0], headings=[0.0, np.pi / 2],
                  starts=[0, 3], goals=[4, 2])
    step = jax.jit(env.step_env)
    limit = round(SETTLE_SECONDS / float(params.dt))
    for t in range(limit + 5):
        _, state, *_ = step(jax.random.key(0), state, jnp.array([1, 1], jnp.int32), params)
        if t < limit - 1:
            assert bool(state.robots.settling[0]), t
    assert bool(state.robots.parked[0]) and not bool(state.robots.settling[0])
    assert int(state.robots.settle_steps[0]) == limit
    assert float(jnp.hypot(state.robots.x[0], state.robots.y[0])) > SETTLE_TOLERANCE


def test_settling_does_not_retrace_across_episodes():
    env, params = make_room(num_agents=2, arrived="settle", time_limit=8.0)
    visited, traces = go_run_counting_traces(env, params, 200)
    assert any(bool(jnp.any(state.robots.settling)) for state, _ in visited)
    assert any(bool(info["episode_done"]) for _, info in visited) and traces == 1


def test_world_semantics_are_validated():
    with pytest.raises(ValueError, match="arrived must be one of"):
        make_room(arrived="stay")
    with pytest.raises(ValueError, match="ended must be one of"):
        make_room(ended="vanish")
    with pytest.raises(ValueError, match="ended must be one of"):
        make_room(ended="settle")  # an ended robot has no goal to settle on
