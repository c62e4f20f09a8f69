"""The local planner: every route of every shipped map is driven to its goal by one robot under
GO within the time limit, without touching a wall; route geometry helpers."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.dynamics.planner import point_along_route, route_progress
from sgjax.evaluation.runner import scan_until_done
from sgjax.maps.arrays import spawn_groups
from sgjax.maps.sampling import build_routes


def all_routes(scenario):
    spec = sgjax.maps.load(scenario)
    pairs = {(s, g) for starts, goals in spawn_groups(spec)
             for s in starts for g in goals if s != g}
    return np.array(sorted(pairs), dtype=np.int32)


@functools.cache
def _route_runner(env, steps: int):
    """``jit(run)(pairs [P, 2], params) -> (succeeded [P], touched [P])``: one robot per
    (start, goal) pair under GO for ``steps`` steps (in chunks of 50 until every robot has
    arrived). The params are an argument, so the robot kinds of one map (params values of one
    environment) share one compiled program."""

    @jax.jit
    def run(pairs, params):
        def reset(pair):
            return env.reset_to(pair[:1], pair[1:], jnp.array([True]), params)[1]

        vstep = jax.vmap(env.step_env, in_axes=(0, 0, 0, None))
        go = jnp.zeros((pairs.shape[0], 1), jnp.int32)

        def step(carry, key):
            state, touched = carry
            _, state, _, _, _, info = vstep(jax.random.split(key, pairs.shape[0]), state, go,
                                            params)
            return state, touched | info["collision_wall"][:, 0]

        init = (jax.vmap(reset)(pairs), jnp.zeros(pairs.shape[0], bool))
        (state, touched), _, _ = scan_until_done(
            step, init, lambda carry: jnp.all(carry[0].robots.succeeded), steps, 50,
            xs=jax.random.split(jax.random.key(0), steps))
        return state.robots.succeeded[:, 0], touched

    return run


def drive_every_route(scenario, robots="socialgym", time_limit=75.0):
    env, params = sgjax.make(scenario, num_agents=1, robots=robots, time_limit=time_limit)
    pairs = all_routes(scenario)
    succeeded, touched = _route_runner(env, int(params.max_steps))(jnp.asarray(pairs), params)
    return pairs, np.asarray(succeeded), np.asarray(touched)


@pytest.mark.slow
@pytest.mark.parametrize("robots", ["socialgym", "jackal", "cobot"])
@pytest.mark.parametrize("scenario", sgjax.registered())
def test_every_route_solved_by_the_planner(scenario, robots):
    pairs, succeeded, touched = drive_every_route(scenario, robots)
    failed = pairs[~succeeded].tolist()
    assert not failed, f"{len(failed)} of {len(pairs)} routes not reached, e.g. {failed[:5]}"
    assert not touched.any(), f"wall contact on routes {pairs[touched].tolist()[:5]}"


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["hallway", "office"])
def test_slow_robot_needs_only_time(scenario):
    # A TurtleBot3 (0.22 m/s) cannot cover the longest routes in 75 s; given 400 s it reaches all.
    pairs, succeeded, touched = drive_every_route(scenario, "turtlebot3", time_limit=400.0)
    assert succeeded.all() and not touched.any()


def test_route_progress_and_carrot_point():
    _, params = sgjax.make("doorway", num_agents=1)
    spec = sgjax.maps.load("doorway")
    start, goal = spec.index_of(0), spec.index_of(22)  # (-7, 0) -> (-2, 0) -> (2, 0) -> (7, 0)
    route = build_routes(params.map, jnp.array([start]), jnp.array([goal]))
    assert float(route.total_length[0]) == pytest.approx(14.0)
    x, y = point_along_route(route, jnp.array([6.5]))
    assert (float(x[0]), float(y[0])) == pytest.approx((-0.5, 0.0))
    end = point_along_route(route, jnp.array([100.0]))
    assert (float(end[0][0]), float(end[1][0])) == pytest.approx((7.0, 0.0))
    p = route_progress(route, jnp.array([-1.0]), jnp.array([0.3]), jnp.array([0.0]))
    assert float(p[0]) == pytest.approx(6.0)
    # Progress never goes back.
    p2 = route_progress(route, jnp.array([-4.0]), jnp.array([0.0]), p)
    assert float(p2[0]) == pytest.approx(6.0)


def test_planner_stops_before_a_robot_in_the_way():
    env, params = sgjax.make("open", num_agents=2)
    spec = sgjax.maps.load("open")
    start = jnp.array([spec.index_of(12), spec.index_of(36)])  # (-6, 0) and (6, 0)
    _, state = env.reset_to(start, start[::-1], jnp.array([True, True]), params)
    state = state.replace(robots=state.robots.replace(x=state.robots.x.at[1].set(-3.0)))
    actions = jnp.array([0, 1], jnp.int32)  # robot 0 GO, robot 1 STOP (an obstacle)
    step = jax.jit(env.step_env)
    for t in range(60):
        _, state, _, _, _, info = step(jax.random.key(t), state, actions, params)
        assert not bool(info["collision_robot"].any()), f"collided at step {t}"


CORRIDOR = {  # 3 m wide, 12 m long, closed at both ends
    "name": "corridor3",
    "description": "a 3 m wide corridor, two lanes of nodes at each end",
    "bounds": [-6.0, -1.5, 6.0, 1.5],
    "walls": [[-6, -1.5, 6, -1.5], [-6, 1.5, 6, 1.5], [-6, -1.5, -6, 1.5], [6, -1.5, 6, 1.5]],
    "nodes": [{"id": 0, "position": [-5.0, 0.0]}, {"id": 1, "position": [5.0, 0.0]},
              {"id": 2, "position": [-5.0, 0.8]}, {"id": 3, "position": [5.0, 0.8]},
              {"id": 4, "position": [-5.0, -0.8]}, {"id": 5, "position": [5.0, -0.8]}],
    "edges": [[0, 1], [2, 3], [4, 5]],
    "groups": [{"starts": [0], "goals": [1]}, {"starts": [1], "goals": [0]},
               {"starts": [2], "goals": [3]}, {"starts": [3], "goals": [2]},
               {"starts": [4], "goals": [5]}, {"starts": [5], "goals": [4]}],
}


def encounter(scenario, starts, goals, seconds, wait=0.0):
    """Robots from node ids ``starts`` to ``goals`` under GO (robot 1 STOPs for the first
    ``wait`` s). Returns each robot's arrival time (s, inf if it never arrived), the smallest
    gap between two robots in the world (m) and the robot collision onsets."""
    spec = sgjax.maps.parse_map(scenario, source="test") if isinstance(scenario, dict) else (
        sgjax.maps.load(scenario))
    n = len(starts)
    env, params = sgjax.make(spec, num_agents=n)
    rows = [jnp.array([spec.index_of(i) for i in ids]) for ids in (starts, goals)]
    _, state = env.reset_to(rows[0], rows[1], jnp.ones(n, bool), params)
    steps = round(seconds / float(params.dt))
    waiting = round(wait / float(params.dt))
    radius = params.robots.radius

    @jax.jit
    def run(state):
        def body(state, t):
            actions = jnp.zeros(n, jnp.int32).at[1].set((t < waiting).astype(jnp.int32))
            _, state, *_ = env.step_env(jax.random.key(0), state, actions, params)
            r = state.robots
            gap = (jnp.hypot(r.x[:, None] - r.x[None, :], r.y[:, None] - r.y[None, :])
                   - radius[:, None] - radius[None, :])
            meet = r.in_world[:, None] & r.in_world[None, :] & ~jnp.eye(n, dtype=bool)
            return state, (r.succeeded, jnp.min(jnp.where(meet, gap, jnp.inf)))

        state, (arrived, gaps) = jax.lax.scan(body, state, jnp.arange(steps))
        return state, arrived, gaps

    state, arrived, gaps = run(state)
    arrived = np.asarray(arrived)
    when = np.where(arrived.any(axis=0), (arrived.argmax(axis=0) + 1) * float(params.dt), np.inf)
    return when, float(np.min(gaps)), np.asarray(state.collisions.robot)


@pytest.mark.parametrize(("scenario", "starts", "goals"), [
    ("open", [12, 36], [36, 12]),  # head-on through the middle
    ("open", [0, 12, 24, 36], [24, 36, 0, 12]),  # four ends swapped through one point
    (CORRIDOR, [0, 1], [1, 0]),  # head-on in a 3 m corridor
    (CORRIDOR, [2, 3, 4, 5], [3, 2, 5, 4]),  # two lanes, both head-on
])
def test_robots_pass_each_other_where_there_is_room(scenario, starts, goals):
    """Where there is room, GO alone passes: every robot arrives within 20 s, none overlaps
    another (gap > 0) and none touches another."""
    when, gap, collisions = encounter(scenario, starts, goals, seconds=20.0)
    assert np.all(when <= 20.0), when
    assert gap > 0.0 and not collisions.any(), (gap, collisions)


@pytest.mark.parametrize(("scenario", "starts", "goals"), [
    ("hallway", [0, 24], [28, 4]),  # the 1 m corridor, head-on
    ("doorway", [0, 24], [28, 4]),  # the 1 m door, head-on
])
def test_a_one_metre_passage_needs_a_stop(scenario, starts, goals):
    """In a 1 m passage two robots cannot pass: GO alone leaves them stuck nose to nose (the
    paper's Only Local deadlock); one STOP until the other is through resolves it."""
    when, _, _ = encounter(scenario, starts, goals, seconds=40.0)
    assert not np.all(when <= 40.0), when
    when, gap, collisions = encounter(scenario, starts, goals, seconds=40.0, wait=15.0)
    assert np.all(when <= 40.0) and gap > 0.0 and not collisions.any(), (when, gap, collisions)
