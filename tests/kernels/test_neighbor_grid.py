"""Neighbour cell lists for pedestrians (``kernels.neighbor_grid``, ``humans.neighbors``):
every body within the range is a candidate, a full list is counted (never a silent miss), and
every force model gives the same forces and trajectories through the lists as over every body
with the same range."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.environment.options import MakeOptions
from sgjax.humans.neighbors import BLOCK, SPAN, dense_pairs, map_pairs
from sgjax.humans.pedestrians import HumanConfig, human_forces
from sgjax.kernels.neighbor_grid import candidates, covering_grid, sort_into_cells
from sgjax.maps.crowd_scenarios import square_crossing

RANGE = 3.0  # m


def random_bodies(key, bodies: int, side: float, absent: float = 0.1):
    """Positions ``[M]`` uniform over a square of ``side`` m (some beyond it) and presence."""
    kx, ky, kp = jax.random.split(key, 3)
    x = jax.random.uniform(kx, (bodies,), minval=-0.1 * side, maxval=1.1 * side)
    y = jax.random.uniform(ky, (bodies,), minval=-0.1 * side, maxval=1.1 * side)
    return x, y, jax.random.uniform(kp, (bodies,)) > absent


@pytest.mark.parametrize("cell", [RANGE, 4.5])
def test_every_body_within_the_range_is_a_candidate(cell):
    """Over 40 random keys, 400 bodies (some outside the grid, some absent): each query's
    candidates hold every present body within the range exactly once, and nothing absent."""
    grid = covering_grid(jnp.zeros(2), (30.0, 20.0), cell)
    capacity = 64

    @jax.jit
    def lists(key):
        x, y, present = random_bodies(key, 400, 25.0)
        cells = sort_into_cells(grid, x, y, present, capacity)
        index, listed = candidates(grid, cells, x, y, capacity)
        return x, y, present, index, listed, cells.overflow

    for seed in range(40):
        x, y, present, index, listed, overflow = map(np.asarray, lists(jax.random.key(seed)))
        assert overflow == 0
        gap = np.hypot(x[:, None] - x[None, :], y[:, None] - y[None, :])
        for q in range(0, 400, 7):
            found = index[q][listed[q]]
            assert len(set(found.tolist())) == len(found)  # no body twice
            assert present[found].all()
            near = set(np.flatnonzero(present & (gap[q] < RANGE)).tolist())
            assert near <= set(found.tolist()), (seed, q, near - set(found.tolist()))


def test_a_full_cell_list_counts_every_body_it_leaves_out():
    """20 bodies in one cell, lists of 8: 12 left out, counted; only 8 are candidates."""
    grid = covering_grid(jnp.zeros(2), (10.0, 10.0), 2.0)

    @jax.jit  # one program, not a dispatch per operation
    def listed(x, y):
        cells = sort_into_cells(grid, x, y, jnp.ones(20, bool), 8)
        return cells.overflow, jnp.sum(candidates(grid, cells, x[:1], y[:1], 8)[1])

    overflow, count = listed(jnp.full(20, 5.1) + 0.01 * jnp.arange(20), jnp.full(20, 5.3))
    assert int(overflow) == 12
    assert int(count) == 8


def crossing_options(model: str, search: str | None, capacity: int = 0) -> dict:
    """``sgjax.make``'s keywords for the 40 m square crossing's 160 pedestrians on their
    routes and 4 robots, with a neighbour range of ``RANGE`` (``search`` None: no range, every
    body)."""
    options = {"num_agents": 4, "num_humans": 160, "human_goals": "routes",
               "human_model": model}
    if search is None:
        return options
    return {**options, "human_range": RANGE, "human_search": search,
            "human_cell_capacity": capacity}


@functools.cache
def crossing(model: str, search: str | None):
    """The crossing with :func:`crossing_options`, made once per module (the tests share the
    environments and their compiled programs)."""
    return sgjax.make(square_crossing(side=40.0), **crossing_options(model, search))


def crowd_config(model: str, search: str | None, capacity: int = 0) -> HumanConfig:
    """The pedestrian configuration ``sgjax.make`` gives :func:`crossing_options` (the same
    ``MakeOptions``; its map, parameters and placement check are not needed)."""
    return MakeOptions.from_keywords(**crossing_options(model, search, capacity)).humans.config()


def forces(config: HumanConfig, substeps: int, robots, humans, params):
    """``human_forces`` of ``config`` for ``robots`` and ``humans`` (the first of
    ``substeps`` sub-steps)."""
    v = robots.body_velocity
    return human_forces(config, params.humans, params.map, humans, robots.x, robots.y,
                        v[:, 0], v[:, 1], robots.in_world, robots.moving,
                        params.robots.radius, params.dt / substeps)


@functools.cache
def rollout(model: str, search: str):
    """200 steps of 160 pedestrians and 4 robots (GO) on the crossing, batched over 2
    environments (``step_batch``): every step's pedestrians, robots and neighbour overflow
    (``[200, 2, ...]``). Run once per module: the forces test reads its states, the
    trajectories test compares the two searches' runs."""
    env, params = crossing(model, search)

    def run(keys):
        _, s = jax.vmap(env.reset, in_axes=(0, None))(keys, params)

        def body(s, k):
            _, s, _, _, _, info = env.step_batch(jax.random.split(k, 2), s,
                                               jnp.zeros((2, 4), jnp.int32), params)
            return s, (s.humans, s.robots, info["neighbor_overflow"])

        return jax.lax.scan(body, s, jax.random.split(jax.random.key(9), 200))[1]

    return jax.jit(run)(jax.random.split(jax.random.key(3), 2))


# The crowd whose states each force law is checked at: the model's own where its trajectories
# are tested too (that rollout is run anyway), else the Moussaid crowd's. The check is per
# state (one state through both searches), so any crowd of 160 on the crossing serves; a
# rollout of its own would cost Helbing's 4.5 s and HSFM's 8 s of CPU (HSFM: 5 sub-steps).
CROWD_OF = {"moussaid": "moussaid", "helbing": "moussaid", "hsfm": "moussaid", "orca": "orca"}


@pytest.mark.parametrize("model", ["moussaid", *(pytest.param(m, marks=pytest.mark.slow)
                                       for m in ("helbing", "hsfm", "orca"))])
def test_forces_through_the_lists_equal_forces_over_every_body(model):
    """Along a 100-step rollout of 160 pedestrians (the first environment of
    :func:`rollout` of the crowd :data:`CROWD_OF` names), at every 10th state: the forces
    through the cell lists equal those over every body with the same range (float rounding of
    the sum's order), and the forces without a range differ (the range matters: the check can
    fail). Lists of one body per cell miss neighbours: counted, and the forces differ."""
    env, params = crossing(model, "all")
    assert crowd_config(model, "all") == env.config.humans  # the configurations make gives
    grid = crowd_config(model, "grid")
    assert grid.uses_grid and not env.config.humans.uses_grid
    # the lists, lists of one body per cell, and no range (the parameters are the dense run's)
    configs = (env.config.humans, grid, crowd_config(model, "grid", 1),
               crowd_config(model, None))
    substeps = env.config.substeps  # the same for every configuration of the model
    # the four configurations' forces in one program (one compile, not four)
    all_forces = jax.jit(lambda r, h, p: tuple(forces(c, substeps, r, h, p) for c in configs))
    humans, robots, _ = rollout(CROWD_OF[model], "all")
    checked = 0
    for t in range(0, 100, 10):  # the state after step t + 1
        dense, listed, tiny, free = all_forces(*jax.tree.map(lambda a, t=t: a[t, 0],
                                                             (robots, humans)), params)
        assert int(listed[4]) == 0 and int(dense[4]) == 0
        scale = float(jnp.max(jnp.abs(jnp.stack(dense[:2]))))
        for a, b in zip(dense[:2], listed[:2], strict=True):
            np.testing.assert_allclose(np.asarray(b), np.asarray(a), atol=1e-5 * scale + 1e-5)
        checked += 1
    assert checked == 10
    assert int(tiny[4]) > 0
    assert float(jnp.max(jnp.abs(tiny[0] - dense[0]))) > 1e-3
    if model in ("moussaid", "helbing"):  # long-range laws: the range changes the forces
        assert float(jnp.max(jnp.abs(free[0] - dense[0]))) > 1e-3


@pytest.mark.slow
@pytest.mark.parametrize("model", ["moussaid", "orca"])
def test_trajectories_through_the_lists_follow_those_over_every_body(model):
    """200 steps of 160 pedestrians and 4 robots (GO), batched over 2 environments: the
    pedestrians' positions through the cell lists stay within 1 cm of those over every body
    (the forces differ by float rounding alone; a crowd amplifies it slowly), nothing
    overflows, and the robots' trajectories agree as closely."""
    assert crossing(model, "grid")[0].config.humans.uses_grid  # the lists are used
    (dense_h, dense_r, dense_o), (listed_h, listed_r, listed_o) = (
        rollout(model, search) for search in ("all", "grid"))
    assert int(jnp.max(listed_o)) == 0 and int(jnp.max(dense_o)) == 0
    for a, b in ((dense_h.x, listed_h.x), (dense_h.y, listed_h.y), (dense_r.x, listed_r.x)):
        assert float(jnp.max(jnp.abs(a - b))) < 1e-2


def test_gradients_flow_through_the_lists():
    """d(sum of forces)/d(positions) through the lists equals the dense one's (the cell
    choice is piecewise constant; the gathered positions carry the gradient)."""
    env, params = crossing("moussaid", "all")
    grid = crowd_config("moussaid", "grid")
    _, state = env.reset(jax.random.key(4), params)

    def total(x, config, s, p):
        out = forces(config, env.config.substeps, s.robots, s.humans.replace(x=x), p)
        return jnp.sum(out[0] ** 2 + out[1] ** 2)

    # both gradients in one program
    dense, listed = jax.jit(lambda x, s, p: (jax.grad(total)(x, env.config.humans, s, p),
                                             jax.grad(total)(x, grid, s, p)))(
        state.humans.x, state, params)
    assert bool(jnp.all(jnp.isfinite(listed)))
    np.testing.assert_allclose(np.asarray(listed), np.asarray(dense), rtol=1e-4, atol=1e-4)


def test_dense_pairs_without_a_range_are_every_other_present_body():
    """Every other present body (robots too), and a grid whose cells span less than the range
    is refused."""
    x, y, present = random_bodies(jax.random.key(0), 30, 10.0)
    pairs = dense_pairs(x[:20], y[:20], x, y, present.astype(jnp.float32), None)
    expected = np.asarray(present, np.float32)[None, :] * (1 - np.eye(20, 30))
    np.testing.assert_array_equal(np.asarray(pairs.weight), expected)
    with pytest.raises(ValueError, match="span at least the neighbour range"):
        map_pairs(lambda p, a, b: (a,), x[:20], y[:20], x, y, present.astype(jnp.float32), (),
                  4.0, covering_grid(jnp.zeros(2), (10.0, 10.0), 1.0), 8)


def test_blocks_of_pedestrians_give_what_all_at_once_give():
    """The cell-list path runs pedestrians in blocks (``lax.map``, the last one padded):
    per-pedestrian outputs equal one block of all of them, for crowd sizes around the block."""
    grid = covering_grid(jnp.zeros(2), (12.0, 12.0), RANGE / SPAN)

    def count(pairs, a, b):
        return (jnp.sum(pairs.weight, axis=1), a * 2.0)

    @functools.partial(jax.jit, static_argnums=0)  # one program per crowd size, both paths
    def both(num, x, y, weight):
        (n_blocks, twice), _ = map_pairs(count, x[:num], y[:num], x, y, weight, (), RANGE,
                                         grid, 64)
        (n_all, _), _ = map_pairs(count, x[:num], y[:num], x, y, weight, (), RANGE, None, 0)
        return n_blocks, twice, n_all

    for num in (5, BLOCK - 1, BLOCK, BLOCK + 3):
        x, y, present = random_bodies(jax.random.key(num), num + 4, 12.0, absent=0.0)
        n_blocks, twice, n_all = both(num, x, y, present.astype(jnp.float32))
        np.testing.assert_array_equal(np.asarray(n_blocks), np.asarray(n_all))
        np.testing.assert_array_equal(np.asarray(twice), 2.0 * np.asarray(x[:num]))


def test_options_name_the_bad_keyword():
    with pytest.raises(ValueError, match="human_range"):
        MakeOptions.from_keywords(num_humans=4, human_range=-1.0)
    with pytest.raises(ValueError, match="human_search"):
        MakeOptions.from_keywords(num_humans=4, human_search="octree")
    with pytest.raises(ValueError, match="needs human_range"):
        MakeOptions.from_keywords(num_humans=4, human_search="grid")
    with pytest.raises(ValueError, match="human_cell_capacity"):
        MakeOptions.from_keywords(num_humans=4, human_cell_capacity=-2)
    assert not HumanConfig(max_humans=500).uses_grid  # no range: every body, as published
    assert HumanConfig(max_humans=1000, neighbor_range=3.0).uses_grid
    assert not HumanConfig(max_humans=1000, neighbor_range=3.0, neighbor_search="all").uses_grid
    assert not HumanConfig(max_humans=20, neighbor_range=3.0).uses_grid  # auto: small crowd
