"""Lidar and line of sight on building floors read the walls from the map's cell lists along
each ray (``sgjax.kernels.walls_along``): the nearest wall of thousands of random rays, the
lidar observation of random robot poses and the line of sight of random pairs equal the
all-walls results on SocialGym 2.0's GDC floors and a dense random floor (rays from outside
the grid included, where a sample reads the cell it is clipped to); small maps keep testing
every wall."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from shared_data import SG2MAPS, require
from test_wall_broad_phase import dense_floor

import sgjax
from sgjax.kernels.walls_along import samples_along, uses_lists_along
from sgjax.observations.lidar import Lidar, wall_distances
from sgjax.terms.contract import TermInput
from sgjax.terms.queries import line_of_sight

RANGE = 5.0  # m: the transfer preset's lidar


def floor(name):
    if name == "dense":
        return dense_floor(seed=3, walls=1500)
    from sgjax.maps.socialgym import import_socialgym

    spec = import_socialgym(require(SG2MAPS / name, "SocialGym 2.0's maps"))
    _, params = sgjax.make(spec, num_agents=2)
    return params.map


def random_rays(m, count, seed, margin=3.0):
    """Ray origins over the walls' extent (and ``margin`` m past it), random directions."""
    rng = np.random.default_rng(seed)
    real = np.asarray(m.wall_valid)
    xs = np.concatenate([np.asarray(m.wall_x1)[real], np.asarray(m.wall_x2)[real]])
    ys = np.concatenate([np.asarray(m.wall_y1)[real], np.asarray(m.wall_y2)[real]])
    px = rng.uniform(xs.min() - margin, xs.max() + margin, count)
    py = rng.uniform(ys.min() - margin, ys.max() + margin, count)
    angle = rng.uniform(-np.pi, np.pi, count)
    return (jnp.asarray(px, jnp.float32), jnp.asarray(py, jnp.float32),
            jnp.asarray(np.cos(angle), jnp.float32), jnp.asarray(np.sin(angle), jnp.float32))


@pytest.mark.parametrize("name", ["dense", "GDC1", "GDC3"])
def test_rays_through_the_lists_meet_the_nearest_wall_as_every_wall(name):
    m = floor(name)
    assert uses_lists_along(m, RANGE) and samples_along(m, RANGE) >= 1
    px, py, ux, uy = random_rays(m, 4000, seed=len(name))
    listed = jax.jit(lambda *a: wall_distances(m, *a, RANGE))(px, py, ux, uy)
    every = jax.jit(lambda *a: wall_distances(m, *a, None))(px, py, ux, uy)
    near = np.asarray(every) <= RANGE
    assert near.sum() > 1000  # most rays meet a wall within range
    np.testing.assert_allclose(np.asarray(listed)[near], np.asarray(every)[near], atol=1e-5)
    assert np.all(np.minimum(np.asarray(listed), RANGE)[~near] == RANGE)


@pytest.mark.parametrize("name", ["dense", "GDC3"])
def test_line_of_sight_within_a_range_through_the_lists_is_the_all_walls_one(name):
    m = floor(name)
    params = type("P", (), {"map": m})()
    px, py, ux, uy = random_rays(m, 4000, seed=7)
    length = jnp.asarray(np.random.default_rng(8).uniform(0.0, RANGE, 4000), jnp.float32)
    qx, qy = px + ux * length, py + uy * length
    listed = line_of_sight(px, py, qx, qy, params, RANGE)
    every = line_of_sight(px, py, qx, qy, params)
    assert 0.1 < float(jnp.mean(listed)) < 0.95  # both outcomes are common
    np.testing.assert_array_equal(np.asarray(listed), np.asarray(every))


def test_the_lidar_of_robots_on_gdc3_equals_the_all_walls_lidar():
    """The lidar term of 4 robots at random poses on GDC3 (through the lists) equals beams
    cast against every wall and the other robots."""
    from sgjax.maps.socialgym import import_socialgym
    from sgjax.observations.lidar import beam_angles, ray_disc_hits

    spec = import_socialgym(require(SG2MAPS / "GDC3", "SocialGym 2.0's maps"))
    env, params = sgjax.make(spec, num_agents=4, observation_preset="transfer")
    lidar = Lidar(beams=16, range=RANGE)
    _, state = env.reset(jax.random.key(0), params)
    px, py, _, _ = random_rays(params.map, 4 * 50, seed=11, margin=0.0)
    heading = np.random.default_rng(12).uniform(-np.pi, np.pi, 4 * 50)
    for k in range(50):
        rows = slice(4 * k, 4 * k + 4)
        kin = state.robots.kin.replace(heading=jnp.asarray(heading[rows], jnp.float32))
        s = state.replace(robots=state.robots.replace(x=px[rows], y=py[rows], kin=kin))
        seen = lidar(TermInput.observing(s, params, env.config.layout, jax.random.key(0)))
        angle = s.robots.heading[:, None] + beam_angles(16, 2 * np.pi)[None, :]
        ux, uy = jnp.cos(angle), jnp.sin(angle)
        walls = wall_distances(params.map, s.robots.x[:, None], s.robots.y[:, None], ux, uy,
                               None)
        bodies = ray_disc_hits(s.robots.x[:, None, None], s.robots.y[:, None, None],
                               ux[..., None], uy[..., None], s.robots.x, s.robots.y,
                               params.robots.radius)
        bodies = jnp.where(jnp.eye(4, dtype=bool)[:, None, :] | ~s.robots.in_world[None, None],
                           jnp.inf, bodies)
        want = jnp.clip(jnp.minimum(walls, jnp.min(bodies, axis=-1)), 0.0, RANGE)
        np.testing.assert_allclose(np.asarray(seen), np.asarray(want), atol=1e-5)


def test_small_maps_and_unbounded_segments_test_every_wall():
    _, params = sgjax.make("doorway", num_agents=2)
    assert not uses_lists_along(params.map, RANGE)
    assert not uses_lists_along(floor("dense"), None)
