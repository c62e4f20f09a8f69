"""The wall broad phase of the contacts (``kernels.contacts.clamp_to_walls`` through the map's
wall grid): the same cut displacements and contact flags as testing every wall, on a dense
random floor and over long rollouts on SocialGym 2.0's building floors; a displacement beyond
the grid's reach is cut, never carried through a wall unseen."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from shared_data import SG2MAPS, require

import sgjax
from sgjax.kernels.contacts import WALL_SKIN, clamp_to_walls, uses_broad_phase
from sgjax.kernels.geometry import point_segment_distance
from sgjax.maps import compile_map, parse_map


def dense_floor(seed: int = 0, walls: int = 600) -> sgjax.maps.MapArrays:
    """``walls`` random short walls (0.2-1.5 m) over a 30 m square, its route outside it."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(-15.0, 15.0, (walls, 2))
    angle = rng.uniform(0.0, 2 * np.pi, walls)
    length = rng.uniform(0.2, 1.5, walls)
    end = start + length[:, None] * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    data = {"name": "dense", "description": "", "bounds": [-25, -25, 25, 25],
            "walls": np.concatenate([start, end], axis=1).tolist(),
            "nodes": [{"id": 0, "position": [-22, -22]}, {"id": 1, "position": [22, -22]}],
            "edges": [[0, 1]], "groups": [{"starts": [0], "goals": [1]}]}
    return compile_map(parse_map(data, clearance=0.5))


def test_the_broad_phase_cuts_every_step_as_every_wall_does():
    """Thousands of discs among 600 walls, every step within the grid's reach: the cut
    displacements equal the all-walls test's to float rounding and the contact flags exactly
    (many of them hit)."""
    m = dense_floor()
    assert uses_broad_phase(m) and not uses_broad_phase(m.replace(reach=0.0))
    rng = np.random.default_rng(1)
    n = 20_000
    x, y = (jnp.asarray(rng.uniform(-16.0, 16.0, n), jnp.float32) for _ in range(2))
    radius = jnp.asarray(rng.uniform(0.05, 0.5, n), jnp.float32)
    step = rng.uniform(0.0, 1.0, n) * (m.reach - np.asarray(radius))  # |d| + r <= reach
    heading = rng.uniform(0.0, 2 * np.pi, n)
    dx = jnp.asarray(step * np.cos(heading), jnp.float32)
    dy = jnp.asarray(step * np.sin(heading), jnp.float32)
    broad = jax.jit(clamp_to_walls)(x, y, dx, dy, radius, m)
    every = jax.jit(clamp_to_walls)(x, y, dx, dy, radius, m.replace(reach=0.0))
    # equal to float rounding (the two programs fuse the same arithmetic differently)
    for a, b in zip(broad[:2], every[:2], strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), atol=1e-5)
    np.testing.assert_array_equal(np.asarray(broad[2]), np.asarray(every[2]))
    assert 0.05 < float(np.mean(every[2])) < 0.95  # both outcomes are exercised


def test_a_step_beyond_the_reach_is_cut_at_it_and_counted_as_a_contact():
    """A displacement longer than the reach (no dynamics makes one) stops where the disc
    would leave the reach, flagged, and never ends inside a wall."""
    m = dense_floor(seed=2)
    rng = np.random.default_rng(3)
    n = 2_000
    x, y = (jnp.asarray(rng.uniform(-16.0, 16.0, n), jnp.float32) for _ in range(2))
    radius = jnp.full(n, 0.3, jnp.float32)
    heading = rng.uniform(0.0, 2 * np.pi, n)
    dx = jnp.asarray(8.0 * np.cos(heading), jnp.float32)
    dy = jnp.asarray(8.0 * np.sin(heading), jnp.float32)
    cx, cy, hit = jax.jit(clamp_to_walls)(x, y, dx, dy, radius, m)
    assert bool(jnp.all(hit))
    assert float(jnp.max(jnp.hypot(cx, cy))) <= m.reach - 0.3 + 1e-5
    ex, ey = np.asarray(x + cx), np.asarray(y + cy)
    walls = np.stack([np.asarray(a) for a in (m.wall_x1, m.wall_y1, m.wall_x2, m.wall_y2)], 1)
    walls = walls[np.asarray(m.wall_valid)]
    start_gap = np.min(np.asarray(point_segment_distance(
        np.asarray(x)[:, None], np.asarray(y)[:, None], *walls.T)), axis=1)
    end_gap = np.min(np.asarray(point_segment_distance(ex[:, None], ey[:, None], *walls.T)),
                     axis=1)
    clear = start_gap > 0.3 + WALL_SKIN  # discs that start outside every wall
    assert clear.sum() > 500
    assert np.all(end_gap[clear] >= 0.3 - 1e-4)


def floor_rollouts(env, params, episodes: int, steps: int = 250) -> tuple[tuple, tuple]:
    """``steps`` steps of ``episodes`` episodes, every robot GO, through the map's wall grid
    and over every wall (its ``reach`` set to 0): each ``(robot x, robot y, pedestrian x,
    pedestrian y)`` at every step."""
    keys = jax.random.split(jax.random.key(0), episodes)
    actions = jnp.zeros((episodes, env.config.max_agents), jnp.int32)

    def rollout(p):
        _, state = jax.vmap(env.reset, in_axes=(0, None))(keys, p)

        def body(state, key):
            state = env.step_batch(jax.random.split(key, episodes), state, actions, p)[1]
            return state, (state.robots.x, state.robots.y, state.humans.x, state.humans.y)

        return jax.lax.scan(body, state, jax.random.split(jax.random.key(1), steps))[1]

    return (jax.jit(rollout)(params),
            jax.jit(rollout)(params.replace(map=params.map.replace(reach=0.0))))


@pytest.mark.slow
@pytest.mark.parametrize("floor, humans", [("GDC1", 24), ("GDC3", 0)])
def test_rollouts_on_building_floors_equal_the_all_walls_rollouts(floor, humans):
    """SocialGym 2.0's GDC floors (1,374 and 5,647 walls), 4 robots always GO (and 24
    pedestrians on GDC1, whose wall contacts take the broad phase too), 250 steps of 4
    episodes: every robot's and pedestrian's position at every step equals the rollout that
    tests every wall."""
    from sgjax.maps.socialgym import import_socialgym

    spec = import_socialgym(require(SG2MAPS / floor, "SocialGym 2.0's maps"))
    env, params = sgjax.make(spec, num_agents=4, num_humans=humans)
    assert uses_broad_phase(params.map)
    broad, every = floor_rollouts(env, params, 4)
    for a, b in zip(broad, every, strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), atol=1e-5)
    moved = np.abs(np.asarray(broad[0][-1]) - np.asarray(broad[0][0])).max()
    assert moved > 1.0  # the robots went somewhere


def walled_crowd(model: str, wall_range: float | None, humans: int = 64, reset: bool = True,
                 **options):
    """A pedestrian environment on a dense floor (600 random walls over a 30 m square, the
    route through it) and (``reset``, else None) a state whose pedestrians stand at random
    places among the walls."""
    rng = np.random.default_rng(5)
    start = rng.uniform(-15.0, 15.0, (600, 2))
    angle = rng.uniform(0.0, 2 * np.pi, 600)
    end = start + rng.uniform(0.2, 1.5, 600)[:, None] * np.stack([np.cos(angle),
                                                                   np.sin(angle)], axis=1)
    data = {"name": "walled", "description": "", "bounds": [-25, -25, 25, 25],
            "walls": np.concatenate([start, end], axis=1).tolist(),
            "nodes": [{"id": 0, "position": [-22, -22]}, {"id": 1, "position": [22, -22]},
                      {"id": 2, "position": [22, 22]}, {"id": 3, "position": [-22, 22]}],
            "edges": [[0, 1], [1, 2], [2, 3], [3, 0]],
            "groups": [{"starts": [0, 1], "goals": [2, 3]}]}
    env, params = sgjax.make(parse_map(data, clearance=0.5), num_agents=2, num_humans=humans,
                             human_model=model, human_range=wall_range, **options)
    if not reset:
        return env, params, None
    _, state = env.reset(jax.random.key(0), params)
    h = state.humans
    x = jnp.asarray(rng.uniform(-15.0, 15.0, humans), jnp.float32)
    y = jnp.asarray(rng.uniform(-15.0, 15.0, humans), jnp.float32)
    vx, vy = (jnp.asarray(rng.uniform(-1.0, 1.0, humans), jnp.float32) for _ in range(2))
    return env, params, state.replace(humans=h.replace(x=x, y=y, vx=vx, vy=vy))


def pedestrian_forces(env, state, params):
    from sgjax.humans.pedestrians import human_forces

    r, h = state.robots, state.humans
    v = r.body_velocity
    return jax.jit(human_forces, static_argnums=0)(
        env.config.humans, params.humans, params.map, h, r.x, r.y, v[:, 0], v[:, 1],
        r.in_world, r.moving, params.robots.radius, params.dt / env.config.substeps)


@pytest.mark.parametrize("model", ["moussaid", "helbing", "hsfm", "orca"])
def test_pedestrians_meet_the_walls_in_range_through_the_lists(model):
    """64 pedestrians among 600 walls with a 3 m range: every model's force through the map's
    cell lists (grown to the range by ``make``) equals its force over every wall with the
    same range, to float rounding of the sums' order; a 1.5 m range gives other forces (the
    comparison can fail), and without a range every wall acts (the lists are not used)."""
    from sgjax.humans.near_walls import uses_wall_lists

    env, params, state = walled_crowd(model, 3.0)
    m = params.map
    assert m.reach >= 3.0 and uses_wall_lists(m, 3.0)
    every = params.replace(map=m.replace(reach=0.0))
    assert not uses_wall_lists(every.map, 3.0)
    listed, dense = (pedestrian_forces(env, state, p) for p in (params, every))
    scale = float(jnp.max(jnp.abs(jnp.stack(dense[:2]))))
    assert scale > 0.1
    for a, b in zip(dense[:2], listed[:2], strict=True):
        np.testing.assert_allclose(np.asarray(b), np.asarray(a), atol=1e-5 * scale + 1e-5)
    short_env, short_params, _ = walled_crowd(model, 1.5, reset=False)  # read at `state`
    short = pedestrian_forces(short_env, state, short_params)
    if model != "hsfm":  # HSFM's wall term is gone by 1.5 m (B = 0.08 m)
        assert float(jnp.max(jnp.abs(short[0] - dense[0]))) > 1e-3
    # without a range the lists are not used, even on this map, whose lists cover 3 m (an
    # environment made without a range: test_a_range_wider_than_the_floor_keeps_the_planners_
    # lists, test_pysocialforce_wall_points_beyond_the_range_do_not_act)
    assert not uses_wall_lists(m, None)


@pytest.mark.slow
def test_a_crowd_on_a_building_floor_follows_the_all_walls_rollout():
    """GDC1 (1,374 walls), 4 robots GO and 120 pedestrians with a 3 m range, 100 steps (10 s)
    of 2 episodes: through the wall lists (contacts and pedestrians' wall terms) every position
    stays within 1 mm of the rollout over every wall with the same range. Not longer: a crowd
    of 120 in corridors is chaotic, and the two paths' float rounding (1e-5 m at 10 s) grows
    to metres by 25 s on some CPUs (an AMD EPYC under the suite's XLA flags; an Intel Xeon
    stayed within 1 mm for 25 s). A missed wall or neighbour shows within the first steps."""
    from sgjax.maps.socialgym import import_socialgym

    spec = import_socialgym(require(SG2MAPS / "GDC1", "SocialGym 2.0's maps"))
    env, params = sgjax.make(spec, num_agents=4, num_humans=120, human_range=3.0)
    listed, every = floor_rollouts(env, params, 2, steps=100)
    for a, b in zip(listed, every, strict=True):
        assert float(np.max(np.abs(np.asarray(a) - np.asarray(b)))) < 1e-3
    moved = np.abs(np.asarray(listed[2][-1]) - np.asarray(listed[2][0])).max()
    assert moved > 1.0


@pytest.mark.slow
def test_a_range_wider_than_the_floor_keeps_the_planners_lists():
    """A 100 m pedestrian range over the 50 m floor puts every wall in range everywhere: the
    map keeps the planner's wall lists (not a grid grown by 100 m on each side, a minute to
    build), pedestrians read every wall, and their forces are those without a range."""
    from sgjax.humans.near_walls import uses_wall_lists

    env, params, state = walled_crowd("helbing", 100.0)
    env_every, without, state_every = walled_crowd("helbing", None)
    assert params.map.reach == without.map.reach < 100.0
    assert params.map.cell_walls.shape == without.map.cell_walls.shape
    assert not uses_wall_lists(params.map, 100.0)
    ranged = np.asarray(pedestrian_forces(env, state, params)[0])
    every = np.asarray(pedestrian_forces(env_every, state_every, without)[0])
    np.testing.assert_allclose(ranged, every, atol=1e-5)
    assert np.max(np.abs(every)) > 0.1


def test_pysocialforce_wall_points_beyond_the_range_do_not_act():
    """The Moussaid wall term over sampled wall points (``human_walls="points"``): a range
    wider than the floor changes nothing, a 1 m range leaves the farther points out."""
    forces = {}
    for wall_range in (None, 100.0, 1.0):
        env, params, state = walled_crowd("moussaid", wall_range, human_walls="points")
        forces[wall_range] = np.asarray(pedestrian_forces(env, state, params)[0])
    np.testing.assert_allclose(forces[100.0], forces[None], atol=1e-5)
    assert np.max(np.abs(forces[1.0] - forces[None])) > 1e-3

