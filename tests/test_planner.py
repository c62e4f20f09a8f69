"""The local planner: every route of every shipped map is driven to its goal by one robot under
GO within the time limit, without touching a wall; route geometry helpers."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.maps.arrays import spawn_groups
from sgjax.maps.sampling import build_routes
from sgjax.planner import point_along_route, route_progress


def all_routes(scenario):
    spec = sgjax.maps.load(scenario)
    pairs = {(s, g) for starts, goals in spawn_groups(spec)
             for s in starts for g in goals if s != g}
    return np.array(sorted(pairs), dtype=np.int32)


def drive_every_route(scenario, robots="socialgym", time_limit=75.0):
    env, params = sgjax.make(scenario, num_agents=1, robots=robots, time_limit=time_limit)
    pairs = all_routes(scenario)
    steps = int(params.max_steps)

    @jax.jit
    def run(pairs):
        def reset(pair):
            return env.reset_to(pair[:1], pair[1:], jnp.array([True]), params)[1]

        state = jax.vmap(reset)(pairs)
        vstep = jax.vmap(env.step_env, in_axes=(0, 0, 0, None))
        go = jnp.zeros((pairs.shape[0], 1), jnp.int32)

        def body(carry, key):
            state, touched = carry
            _, state, _, _, _, info = vstep(jax.random.split(key, pairs.shape[0]), state, go,
                                            params)
            return (state, touched | info["collision_wall"][:, 0]), None

        init = (state, jnp.zeros(pairs.shape[0], bool))
        (state, touched), _ = jax.lax.scan(body, init, jax.random.split(jax.random.key(0), steps))
        return state.robots.succeeded[:, 0], touched

    succeeded, touched = run(jnp.asarray(pairs))
    return pairs, np.asarray(succeeded), np.asarray(touched)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", sgjax.registered())
@pytest.mark.parametrize("robots", ["socialgym", "jackal", "cobot"])
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
