"""Generated worlds (``sgjax.maps.generated``): over thousands of keys every world of every
family is valid, connected and deterministic, ``vmap`` gives each key's world, the in-``jit``
graph and wall grid are the host's, and the exported files pass ``sgjax maps check``; the
checks fail on worlds built broken (a node in a wall, an edge through a wall, no dilemma)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from long_runs import jit_for_long_runs

from sgjax.maps.check import check_map
from sgjax.maps.generated.checks import verdict
from sgjax.maps.generated.compiled import world_arrays
from sgjax.maps.generated.export import world_map
from sgjax.maps.generated.families import FAMILIES, family
from sgjax.maps.generated.family import draw_values, generate, range_arrays
from sgjax.maps.routing import all_pairs_shortest_paths
from sgjax.maps.schema import parse_map

KEYS = 2048  # worlds per family in the property test
RADIUS = 0.3  # m: the widest robot the checks are asked about
# The families whose checks over KEYS worlds run far longer than they compile (many hubs, long
# routes): compiled with the backend optimised (tests/long_runs.py), which the suite turns off.
# Measured on the 2-core CPU: the floor plans' 2,048 worlds in 4.5 s of CPU instead of 14 s,
# the open spaces' in 2 s instead of 3 s; the other families run about as long as they compile,
# and compile faster unoptimised.
RUN_BOUND = ("open", "floorplan")


_BATCHES: dict[str, tuple] = {}  # family -> its KEYS worlds, once a test has made them


def batch(name: str, count: int = KEYS):
    """The worlds of family ``name`` of the first ``count`` of the property test's keys:
    (worlds, values, arrays, verdicts, (dist, hops)), ``dist`` and ``hops`` the routes'
    lengths and node hops (``hops`` None for the families routed by the generic
    Floyd-Warshall). Fewer than ``KEYS`` are sliced from the ``KEYS`` worlds where a test has
    made them already (the same keys, the same worlds). All ``KEYS`` worlds of the
    :data:`RUN_BOUND` families one at a time (``lax.map``: unbatched, the floor plans'
    dilemma check, gathers and scatters per world, runs faster) and :func:`jit_for_long_runs`."""
    if name in _BATCHES:  # sliced on the host (a slice per array in JAX is a compile each)
        return jax.tree.map(lambda x: np.asarray(x)[:count], _BATCHES[name])
    fam = FAMILIES[name]
    ranges = range_arrays(fam.ranges())

    def one(key):
        world, values = generate(fam, key, ranges)
        arrays, dist, overflow, hops = world_arrays(world, fam.capacity, fam.routes)
        return world, values, arrays, verdict(world, dist, arrays.next_hop, overflow, RADIUS,
                                              route_nodes=fam.capacity.route_nodes,
                                              hops=hops), (dist, hops)

    keys = jax.random.split(jax.random.key(0), KEYS)[:count]
    if count < KEYS or name not in RUN_BOUND:
        made = jax.jit(jax.vmap(one))(keys)
    else:
        made = jit_for_long_runs(lambda keys: jax.lax.map(one, keys))(keys)
    if count == KEYS:
        _BATCHES[name] = made
    return made


def one_world(out, i):
    return jax.tree.map(lambda x: np.asarray(x[i]), out)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(FAMILIES))
def test_every_world_of_thousands_of_keys_is_valid(name):
    worlds, values, arrays, v, _ = batch(name)
    checks = {k: np.asarray(getattr(v, k)) for k in ("made", "clearance", "edges_clear",
                                                      "connected", "routes_fit", "passages",
                                                      "grid", "dilemma")}
    assert {k: int((~c).sum()) for k, c in checks.items()} == dict.fromkeys(checks, 0)
    fam = FAMILIES[name]
    for key, value in values.items():  # every value inside its range
        low, high = fam.ranges()[key]
        assert np.all((np.asarray(value) >= low - 1e-6) & (np.asarray(value) <= high + 1e-6))
    # worlds differ from key to key
    assert len({tuple(np.round(np.asarray(w), 4)) for w in worlds.walls[:64, 0]}) > 32


@pytest.mark.parametrize("name", list(FAMILIES))
def test_the_same_key_gives_the_same_world_and_vmap_gives_each_keys(name):
    """Shapes and values stable under ``vmap``."""
    fam = FAMILIES[name]
    ranges = range_arrays(fam.ranges())
    keys = jax.random.split(jax.random.key(7), 4)
    single = jax.jit(lambda k: generate(fam, k, ranges))
    together = jax.jit(jax.vmap(lambda k: generate(fam, k, ranges)))(keys)
    for i, key in enumerate(keys):
        alone = single(key)
        again = single(key)
        for a, b, c in zip(jax.tree.leaves(alone), jax.tree.leaves(again),
                           jax.tree.leaves(together), strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))  # deterministic
            # vmap: each key's world, up to float32 rounding of a differently fused program
            np.testing.assert_allclose(np.asarray(a), np.asarray(c)[i], rtol=1e-6, atol=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(FAMILIES))
def test_exported_worlds_pass_the_map_checker_and_compile_to_the_same_routes(name):
    worlds, values, arrays, _, _ = jax.device_get(batch(name))  # read on the host
    fam = FAMILIES[name]
    for i in range(0, KEYS, KEYS // 24):
        world, arr = one_world(worlds, i), one_world(arrays, i)
        data = world_map(world, f"{name}-{i}", fam.description,
                         {k: v[i] for k, v in values.items()})
        problems = check_map(data, f"{name}-{i}", clearance=RADIUS)
        assert [p for p in problems if p.severity == "error"] == [], i
        # a floor plan's zones are all its doors: those off the two pairs' routes see no robot
        idle = [p for p in problems if "no robot's shortest route crosses" in p.message]
        assert len(idle) < len(data["zones"]) if name == "floorplan" else not idle
        assert not [p for p in problems if "enclosed" in p.message
                    or ("no robot" in p.message and p not in idle)]
        spec = parse_map(data, source=f"{name}-{i}", clearance=RADIUS)
        dist, _ = all_pairs_shortest_paths(spec.node_positions, spec.edges)
        kept = np.flatnonzero(world.node_valid)  # the exported nodes, in row order
        ours = np.asarray(arr.path_length)[np.ix_(kept, kept)]
        np.testing.assert_allclose(np.where(np.isfinite(dist), dist, -1.0), ours, rtol=1e-5,
                                   atol=1e-4)


def walk_routes(next_hop: np.ndarray, gap: np.ndarray, hops: int, chunk: int = 16
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (start, goal) route of every world walked hop by hop along ``next_hop [W, N, N]``
    (an unreachable goal's -1 read as node 0, as the routes' users read it) for at most
    ``hops`` hops: ``(at, walked, steps)`` ``[W, N, N]``, where each route ends, the length
    (m, summed over ``gap [W, N, N]``) and the hops it took. On the host, a chunk of worlds at
    a time, and a route that stops moving is dropped: from then on every hop would leave it
    where it is (so the result is the full ``hops``-hop walk's; a vmapped in-jit walk of
    gathers cost 20 s of the suite's CPU for 2,048 floor plans, this walk about 2 s)."""
    worlds, count, _ = next_hop.shape
    at_all = np.empty(next_hop.shape, np.int32)
    walked_all = np.zeros(next_hop.shape, np.float32)
    steps_all = np.zeros(next_hop.shape, np.int32)
    for first in range(0, worlds, chunk):
        hop_of = next_hop[first:first + chunk].reshape(-1)
        gap_of = gap[first:first + chunk].reshape(-1)
        route = np.arange(hop_of.size, dtype=np.int32)  # world * N^2 + start * N + goal
        goal = route % count
        at = (route // count) % count
        column = route - at * count  # world * N^2 + goal: next_hop[world, i, goal] is at
        # column + i N, gap[world, i, j] at column - goal + i N + j
        end, walked, steps = at.copy(), np.zeros(route.size, np.float32), np.zeros_like(route)
        for _ in range(hops):
            hop = np.maximum(hop_of[column + at * count], 0)
            moved = hop != at
            if not moved.any():
                break
            route, goal, column, at, hop = (a[moved] for a in (route, goal, column, at, hop))
            walked[route] += gap_of[column - goal + at * count + hop]
            steps[route] += 1
            end[route] = at = hop
        for out, value in ((at_all, end), (walked_all, walked), (steps_all, steps)):
            out[first:first + chunk] = value.reshape(-1, count, count)
    return at_all, walked_all, steps_all


@pytest.mark.slow
def test_a_floor_plans_own_routes_equal_floyd_warshall_and_walk_in_their_hops():
    """The floor plan's routes from its structure (rooms' Floyd-Warshall, the other nodes hung
    off them) over the thousands of worlds of the property test: every length the generic
    Floyd-Warshall's over all hubs, every route walked along ``next_hop`` reaches its goal in
    exactly its ``hops`` with the length ``dist`` gives (so a route that fits by ``hops``
    fits when walked)."""
    from sgjax.maps.generated.checks import routes_fit
    from sgjax.maps.generated.graph import shortest_paths

    fam = family("floorplan")
    worlds, _, arrays, _, (dist, hops) = batch("floorplan")  # the family's own routes
    count, route_nodes = fam.capacity.nodes, fam.capacity.route_nodes

    def compare(args):
        world, gap, next_hop, hops = args
        generic, _, fits = shortest_paths(gap, world.adjacency, fam.capacity.hubs)
        return (generic, fits, routes_fit(world, next_hop, route_nodes),
                routes_fit(world, next_hop, route_nodes, hops))

    # a world at a time (Floyd-Warshall's dynamic slices stay slices, not batched gathers)
    out = jit_for_long_runs(lambda *args: jax.lax.map(compare, args))(
        worlds, arrays.node_gap, arrays.next_hop, hops)
    generic, fits, walk_fits, by_hops = map(np.asarray, out)
    dist, hops = np.asarray(dist), np.asarray(hops)
    at, walked, steps = walk_routes(np.asarray(arrays.next_hop), np.asarray(arrays.node_gap),
                                    route_nodes)
    arrived = at == np.arange(count)[None, None, :]
    assert fits.all()
    finite = np.isfinite(generic)
    assert (np.isfinite(dist) == finite).all()
    np.testing.assert_allclose(dist[finite], generic[finite], rtol=1e-5, atol=1e-4)
    # every reachable route arrives, in its hops, along its length; the unreachable ones
    # have hops -1
    assert arrived[finite].all() and (steps[finite] == hops[finite]).all()
    np.testing.assert_allclose(walked[finite], dist[finite], rtol=1e-5, atol=1e-4)
    assert (hops[~finite] == -1).all()
    assert (walk_fits == by_hops).all() and by_hops.all()


def test_the_wall_grid_matches_the_hosts_on_the_familys_extent():
    """The planner's per-cell wall lists: where a family's cells hold fewer than all its walls,
    the in-jit grid equals the host's ``wall_grid`` on the same grid (the family's extent);
    where they hold all of them (the shipped families), one cell lists every wall slot."""
    import dataclasses

    from sgjax.maps.arrays import wall_grid
    from sgjax.maps.generated.grid import cell_walls, grid_layout

    fam = family("hallway")
    worlds, _, arrays, _, _ = batch("hallway", 64)
    assert np.asarray(arrays.cell_walls).shape == (64, 1, fam.capacity.walls - 1)
    capacity = dataclasses.replace(fam.capacity, cell_walls=10)
    origin, (nx, ny) = grid_layout(capacity)
    hi = origin + np.asarray([nx, ny]) * capacity.cell_size
    lists_of = jax.jit(lambda w: cell_walls(w.walls, w.wall_valid, capacity))
    for i in range(0, 64, 9):
        world = one_world(worlds, i)
        ours, overflow = lists_of(world)
        host, _, shape = wall_grid(world.walls.astype(np.float64), world.wall_valid,
                                   origin, hi, capacity.reach, capacity.cell_size)
        assert shape == (nx, ny) and not bool(overflow)
        pad = world.walls.shape[0] - 1
        ours = [sorted(int(w) for w in cell if w != pad) for cell in np.asarray(ours)]
        host = [sorted(int(w) for w in cell if w != pad) for cell in host]
        assert ours == host
    tight = dataclasses.replace(fam.capacity, cell_walls=3)
    assert bool(jax.jit(lambda w: cell_walls(w.walls, w.wall_valid, tight))(
        one_world(worlds, 0))[1])  # more near walls than a cell holds: flagged


def _broken(mutate):
    """A doorway world of key 3, changed by ``mutate(world) -> world``, and its verdict."""
    fam = family("doorway")

    @jax.jit
    def made(key):
        world = mutate(generate(fam, key, range_arrays(fam.ranges()))[0])
        arrays, dist, overflow, _ = world_arrays(world, fam.capacity)
        return world, verdict(world, dist, arrays.next_hop, overflow, RADIUS,
                              route_nodes=fam.capacity.route_nodes)

    return made(jax.random.key(3))


def _exported_errors(world):
    data = world_map(jax.tree.map(np.asarray, world), "broken", "a broken doorway")
    return [p for p in check_map(data, "broken", clearance=RADIUS) if p.severity == "error"]


def test_a_node_in_a_wall_fails_both_checks():
    # a spawn moved onto the room's left wall
    world, v = _broken(lambda w: w.replace(nodes=w.nodes.at[5].set(w.walls[2, :2] + 0.05)))
    assert not bool(v.clearance) and not bool(v.valid)
    assert any("wall" in p.message for p in _exported_errors(world))


def test_an_edge_through_a_wall_fails_both_checks():
    # a spawn of the left room joined straight to the right room's approach node: through the
    # wall beside the door (the spawn moved to the door wall's height)
    def mutate(w):
        top = w.walls[3]  # the left face above the door
        spawn = jnp.stack([w.nodes[5, 0], (top[1] + top[3]) / 2])
        # the spawn's edge (row 4 of the edge list: spawn 5 to the left approach node) now
        # goes to the right room's approach node instead
        return w.replace(nodes=w.nodes.at[5].set(spawn), edges=w.edges.at[4].set(
            jnp.asarray([1, 5], jnp.int32)))

    world, v = _broken(mutate)
    assert not bool(v.edges_clear)
    assert any("crosses wall" in p.message for p in _exported_errors(world))


def test_the_dilemma_check_fails_on_a_world_without_one():
    # one flow only (the right room's robots do not cross): no conflicting directions
    def one_way(w):
        return w.replace(group_starts=w.group_starts.at[1].set(False))

    world, v = _broken(one_way)
    assert bool(v.clearance) and bool(v.connected) and not bool(v.dilemma)
    _, whole = _broken(lambda w: w)
    assert bool(whole.dilemma) and bool(whole.valid)


def test_a_passage_narrower_than_the_robots_is_flagged():
    fam = family("doorway")
    ranges = range_arrays(fam.ranges({"door_width": 0.6}))

    @jax.jit
    def passages(key):
        world, _ = generate(fam, key, ranges)
        arrays, dist, overflow, _ = world_arrays(world, fam.capacity)
        return [verdict(world, dist, arrays.next_hop, overflow, radius, check_dilemma=False
                        ).passages for radius in (0.3, 0.2)]

    wide, narrow = passages(jax.random.key(0))
    assert not bool(wide) and bool(narrow)


def test_ranges_are_checked_against_the_family():
    fam = family("generated:doorway")
    with pytest.raises(ValueError, match="no parameter 'door_widht'.*door_width"):
        fam.ranges({"door_widht": (1, 2)})
    with pytest.raises(ValueError, match=r"door_width range \[0.5, 1\] must lie within"):
        fam.ranges({"door_width": (0.5, 1.0)})
    with pytest.raises(ValueError, match="no world family 'dorway'.*doorway"):
        family("dorway")


def test_draws_stay_in_their_ranges_and_one_parameter_does_not_move_the_others():
    ranges = range_arrays({"a": (0.0, 1.0), "b": (5.0, 6.0)})
    wider = range_arrays({"a": (0.0, 1.0), "b": (5.0, 6.0), "c": (1.0, 2.0)})
    key = jax.random.key(11)
    one, two = draw_values(key, ranges), draw_values(key, wider)
    assert 0.0 <= float(one["a"]) <= 1.0 and 5.0 <= float(one["b"]) <= 6.0
    assert float(one["a"]) == float(two["a"]) and float(one["b"]) == float(two["b"])


def test_the_docs_list_every_familys_parameters_with_their_ranges():
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "generated.md").read_text()
    for name, fam in FAMILIES.items():
        section = text.split(f"### `{name}`")[1].split("###")[0]
        rows = dict(re.findall(r"^\| `(\w+)` \| ([^|]+) \|", section, re.M))
        assert set(rows) == set(fam.parameters), name
        for key, parameter in fam.parameters.items():
            low, high = (float(v) for v in rows[key].replace(" - ", " ").split())
            assert (low, high) == parameter.default, (name, key)


def test_pointer_doubling_finds_the_routes_that_walking_finds():
    """Floor plans' long routes are followed by pointer doubling: where every route is after
    any number of hops, and the edges the routes take, equal a hop-by-hop walk's."""
    from sgjax.maps.generated.checks import (
        WALK_HOPS,
        after_hops,
        group_pairs,
        route_steps,
        used_edges,
    )

    fam = FAMILIES["floorplan"]
    worlds, _, arrays, _, _ = batch("floorplan", 64)
    assert fam.capacity.route_nodes - 1 > WALK_HOPS
    for i in range(0, 64, 8):
        world, hop = one_world(worlds, i), jnp.asarray(one_world(arrays, i).next_hop)
        steps = route_steps(hop, fam.capacity.route_nodes - 1)
        for hops in (WALK_HOPS + 1, 13, fam.capacity.route_nodes - 1):
            np.testing.assert_array_equal(np.asarray(after_hops(hop, hops)),
                                          np.asarray(steps[hops - 1][1]))
        pairs = np.asarray(group_pairs(world))
        walked = np.zeros(hop.shape, bool)
        for at, nxt in steps:
            at, nxt = np.asarray(at), np.asarray(nxt)
            moved = pairs & (nxt != at)
            walked[at[moved], nxt[moved]] = True
        used = np.asarray(used_edges(world, hop, fam.capacity.route_nodes))
        np.testing.assert_array_equal(used, walked)
        assert walked.sum() > 0


@pytest.mark.parametrize("name", ["doorway", "hallway"])
def test_one_way_worlds_send_every_robot_left_to_right_and_promise_no_dilemma(name):
    """``ways`` below 1.5: both spawn groups start in the left room and end in the right (a
    queue at a bottleneck, SocialGym 2.0's doorway), the world promises no dilemma (so the
    dilemma check passes it), the exported file passes the map checker; the same key at the
    default (both ways) gives the same geometry with opposed groups; ``[1, 2]`` mixes both."""
    fam = FAMILIES[name]
    keys = jax.random.split(jax.random.key(3), 64)

    @jax.jit  # one program for the three ranges (arrays, traced)
    def worlds(ranges):
        def one(key):
            world, values = generate(fam, key, ranges)
            arrays, dist, overflow, hops = world_arrays(world, fam.capacity, fam.routes)
            return world, values, verdict(world, dist, arrays.next_hop, overflow, RADIUS,
                                          route_nodes=fam.capacity.route_nodes, hops=hops)
        return jax.vmap(one)(keys)

    one_way, values, checked = worlds(range_arrays(fam.ranges({"ways": 1.0})))
    both, _, both_checked = worlds(range_arrays(fam.ranges()))
    starts, goals = np.asarray(one_way.group_starts), np.asarray(one_way.group_goals)
    np.testing.assert_array_equal(starts[:, 0], starts[:, 1])
    np.testing.assert_array_equal(goals[:, 0], goals[:, 1])
    nodes = np.asarray(one_way.nodes)
    assert np.all(np.where(starts[:, 0], nodes[..., 0], -np.inf) < 0.0)  # the left room
    assert np.all(np.where(goals[:, 0], nodes[..., 0], np.inf) > 0.0)  # to the right one
    assert not np.asarray(one_way.dilemma).any() and np.asarray(checked.valid).all()
    assert np.asarray(both.dilemma).all() and np.asarray(both_checked.valid).all()
    np.testing.assert_array_equal(np.asarray(one_way.walls), np.asarray(both.walls))
    np.testing.assert_array_equal(np.asarray(both.group_starts)[:, 1],
                                  np.asarray(both.group_goals)[:, 0])
    world = one_world(one_way, 0)
    data = world_map(world, f"{name}-one-way", fam.description,
                     {k: v[0] for k, v in values.items()})
    assert [p for p in check_map(data, f"{name}-one-way", clearance=RADIUS)
            if p.severity == "error"] == []
    mixed, _, _ = worlds(range_arrays(fam.ranges({"ways": (1.0, 2.0)})))
    promised = np.asarray(mixed.dilemma)
    assert 0 < promised.sum() < len(promised)
