"""The generated crowd scenarios (sgjax/maps/crowd_scenarios.py): registered, sampled inside reset,
with
pedestrians walking their routes, and usable under every pedestrian model."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.maps import parse_map
from sgjax.maps.crowd_scenarios import (
    CROWD_SCENARIOS,
    circle_crossing,
    perpendicular_traffic,
    resize,
)


def test_crowd_scenarios_are_registered_and_reset_on_their_routes():
    assert set(CROWD_SCENARIOS) <= set(sgjax.registered())
    for name in CROWD_SCENARIOS:
        env, params = sgjax.make(name, num_agents=2, num_humans=12)
        assert env.config.humans.goal_mode == "routes"
        keys = jax.random.split(jax.random.key(0), 4)
        _, states = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
        h = states.humans
        m = params.map
        starts, goals = np.asarray(params.humans.route_start), np.asarray(params.humans.route_goal)
        pairs = set(zip(starts.tolist(), goals.tolist(), strict=True))
        origin, goal = np.asarray(h.origin), np.asarray(h.goal)
        assert all((o, g) in pairs for o, g in zip(origin.ravel(), goal.ravel(), strict=True))
        # Each pedestrian stands on a spawn slot near its route's start.
        near = np.hypot(np.asarray(h.x) - np.asarray(m.node_x)[origin],
                        np.asarray(h.y) - np.asarray(m.node_y)[origin])
        assert near.max() < 2.5, (name, near.max())
        assert not np.array_equal(np.asarray(h.x[0]), np.asarray(h.x[1]))  # sampled per key


def test_circle_crossing_heads_for_the_opposite_point_and_takes_settings():
    spec = circle_crossing(radius=6.0, points=8)
    env, params = sgjax.make(spec, num_agents=1, num_humans=6)
    assert env.config.humans.goal_mode == "routes"
    starts = np.asarray(params.humans.route_start)
    goals = np.asarray(params.humans.route_goal)
    xy = np.stack([np.asarray(params.map.node_x), np.asarray(params.map.node_y)], axis=1)
    np.testing.assert_allclose(np.hypot(*xy[starts].T), 6.0, atol=1e-5)
    np.testing.assert_allclose(xy[goals], -xy[starts], atol=1e-5)
    with pytest.raises(ValueError, match="points an even number"):
        circle_crossing(points=5)
    assert parse_map(spec.to_json(), source="again").groups == spec.groups


def test_perpendicular_traffic_crosses_robots_and_pedestrians():
    """Robots travel west-east, pedestrians south-north: their routes are perpendicular."""
    spec = perpendicular_traffic()
    env, params = sgjax.make(spec, num_agents=2, num_humans=8)
    xy = np.stack([np.asarray(params.map.node_x), np.asarray(params.map.node_y)], axis=1)
    walk = xy[np.asarray(params.humans.route_goal)] - xy[np.asarray(params.humans.route_start)]
    assert np.allclose(walk[:, 0], 0.0) and np.all(np.abs(walk[:, 1]) > 10)
    _, state = env.reset(jax.random.key(3), params)
    drive = state.route.goal_x - state.route.x[:, 0], state.route.goal_y - state.route.y[:, 0]
    assert np.all(np.abs(np.asarray(drive[0])) > 10) and np.allclose(np.asarray(drive[1]), 0.0)
    assert spec.to_json()["pedestrian_groups"]


@pytest.mark.slow
@pytest.mark.parametrize("model", ["moussaid", "helbing", "orca", "hsfm"])
def test_circle_crossing_runs_under_every_model(model):
    """20 pedestrians and 2 robots crossing the 4 m circle for 300 steps: finite, and most
    pedestrians get across (over 6 m from where they started, at some point)."""
    env, params = sgjax.make("circle_crossing", num_agents=2, num_humans=20, human_model=model)
    _, state = env.reset(jax.random.key(0), params)
    x0, y0 = state.humans.x, state.humans.y

    def body(s, k):
        s = env.step(k, s, jnp.zeros(2, jnp.int32), params)[1]
        return s, jnp.hypot(s.humans.x - x0, s.humans.y - y0)

    state, away = jax.jit(lambda s: jax.lax.scan(body, s, jax.random.split(jax.random.key(1),
                                                                          300)))(state)
    assert np.all(np.isfinite(np.asarray(state.humans.x)))
    assert float(np.min(np.hypot(np.asarray(x0), np.asarray(y0)))) > 2.5  # on the circle
    across = np.max(np.asarray(away), axis=0) > 6.0
    assert across.mean() >= 0.75, np.max(np.asarray(away), axis=0)


def test_resize_sweeps_the_circle_radius_as_a_traced_param():
    """``crowd.resize`` scales the routes by a traced factor: one compiled reset serves every
    radius, robots and pedestrians start on the scaled circle, and the episode plays out."""
    env, params = sgjax.make(circle_crossing(radius=6.0), num_agents=3, num_humans=8)
    traces = []

    @jax.jit
    def reset_at(scale, key):
        traces.append(1)
        p = params.replace(map=resize(params.map, scale))
        return env.reset(key, p)[1], p

    for scale in (0.5, 1.0 / 3.0):
        state, p = reset_at(jnp.float32(scale), jax.random.key(2))
        radius = 6.0 * scale
        start = np.hypot(np.asarray(state.route.x[:, 0]), np.asarray(state.route.y[:, 0]))
        np.testing.assert_allclose(start, radius, atol=1e-4)
        np.testing.assert_allclose(np.asarray(state.route.goal_x), -np.asarray(state.route.x[:, 0]),
                                   atol=1e-4)
        origin = np.asarray(state.humans.origin)
        np.testing.assert_allclose(np.hypot(np.asarray(p.map.node_x)[origin],
                                            np.asarray(p.map.node_y)[origin]), radius, atol=1e-4)
        near = np.hypot(np.asarray(state.humans.x) - np.asarray(p.map.node_x)[origin],
                        np.asarray(state.humans.y) - np.asarray(p.map.node_y)[origin])
        assert near.max() < 1.0, near
    assert len(traces) == 1  # the radius is a param: no retrace

    # A vmap over radii runs the episodes; robots on the 2 m circle arrive sooner than on 6 m
    # (steps until each robot first arrives; an episode resets once all have finished).
    scales = jnp.asarray([1.0 / 3.0, 1.0])

    def episode(scale):
        p = params.replace(map=resize(params.map, scale))
        s = env.reset(jax.random.key(4), p)[1]

        def body(s, k):
            s = env.step(k, s, jnp.zeros(3, jnp.int32), p)[1]
            return s, s.robots.succeeded

        return jax.lax.scan(body, s, jax.random.split(jax.random.key(5), 160))[1]

    arrived = np.asarray(jax.jit(jax.vmap(episode))(scales))  # [2, T, R]
    first = np.where(arrived.any(axis=1), np.argmax(arrived, axis=1), 10**6)  # first arrival
    assert (first[0] < 160).all(), first  # every robot crosses the 2 m circle in 16 s
    assert (first[0] < first[1]).all(), first
    with pytest.raises(ValueError, match=r"scale must be in \(0, 1\]"):
        resize(params.map, 1.5)
