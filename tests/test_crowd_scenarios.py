"""The generated crowd scenarios (sgjax/maps/crowd.py): registered, sampled inside reset, with
pedestrians walking their routes, and usable under every pedestrian model."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.maps import parse_map
from sgjax.maps.crowd import CROWD_SCENARIOS, circle_crossing, perpendicular_traffic


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
