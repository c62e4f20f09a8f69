"""Shortest routes of a floor plan from its structure, inside ``jit``: Floyd-Warshall over the
rooms alone, the other nodes hung off them.

A floor plan's graph (:mod:`sgjax.maps.generated.floorplan`) is rooms joined by doors: every
door is a chain room ``a`` - near approach - far approach - room ``b``, every spawn a leaf off
its room. A path from one room to another passes room centres and door chains only, so the
rooms' own graph (one edge per door, its chain's length) holds every route: Floyd-Warshall over
16 rooms (``16^3`` work, not the ``64^3`` of the generic hub matrix,
:func:`sgjax.maps.generated.graph.shortest_paths`). Every node is attached to at most two
rooms, each at an offset (m) and a number of hops: a centre to itself, an approach node to both
ends of its chain, a spawn to its room. The length of ``i -> j`` is the least of
``offset_i + rooms(hub_i, hub_j) + offset_j`` over the attachments, or the chain itself for
the two approach nodes of one door; the next node follows the room route. The hop counts of
the routes come with them (the room route walked hop by hop, three node hops per room hop), so
whether a route fits the route arrays needs no walk along ``next_hop`` (tests walk it)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jax import Array

from sgjax.maps.generated.checks import route_steps
from sgjax.maps.generated.floorplan_layout import (
    CELLS,
    DOORS,
    FIRST_APPROACH,
    FIRST_SPAWN,
    NODES,
    PAIRS,
    SLOTS,
    SPAWNS,
)
from sgjax.maps.generated.graph import relaxed
from sgjax.maps.routing import NO_PATH

NEAR = FIRST_APPROACH + np.arange(DOORS)  # door e's approach node on its first room's side
FAR_SIDE = FIRST_APPROACH + DOORS + np.arange(DOORS)  # ... on its second room's side
SPAWN_ROWS = FIRST_SPAWN + np.arange(SLOTS * SPAWNS)
ROOM_A, ROOM_B = PAIRS[:, 0], PAIRS[:, 1]
SPAWN_EDGES = 3 * DOORS  # the first edge row joining a spawn to its room (floorplan.build)


def _entry_steps() -> np.ndarray:
    """``[CELLS, CELLS]``: the node a route from the first room enters the door to the second,
    a neighbouring room, by (its approach node on the first room's side; ``NO_PATH`` for
    rooms that are not neighbours)."""
    step = np.full((CELLS, CELLS), NO_PATH, np.int32)
    for e, (a, b) in enumerate(PAIRS):
        step[a, b], step[b, a] = NEAR[e], FAR_SIDE[e]
    return step


ENTRY_STEP = _entry_steps()
# a node's kind: centre, approach (either side) or spawn
IS_CENTRE = np.arange(NODES) < CELLS
IS_APPROACH = (np.arange(NODES) >= FIRST_APPROACH) & (np.arange(NODES) < FIRST_SPAWN)


def room_hops(next_room: Array) -> Array:
    """``[R, R]`` int32: the rooms a route passes after its first (its room hops), walking
    ``next_room`` (a route of the rooms' graph has fewer than ``R`` hops)."""
    count = next_room.shape[0]
    return sum((hop != at).astype(jnp.int32) for at, hop in route_steps(next_room, count - 1))


def attachments(gap: Array, adjacency: Array, edges: Array) -> tuple[Array, ...]:
    """Each node's two attachments to rooms: ``(hub, offset, hops, first, entry)``, ``[N, 2]``
    each: the room, the length to it (m, ``inf`` where the node or a link is missing), the
    node hops to it, the first node on the way from the node to the room, and the last before
    the node on the way from the room to it. A centre is attached to itself (its second
    attachment unused), an approach node to its door's first room and, through its partner, the
    second, a spawn to its room (read from its edge)."""
    centres = np.arange(CELLS)
    room_of_spawn = edges[SPAWN_EDGES:, 0]  # [SLOTS * SPAWNS]
    inf = jnp.inf
    ab, nf, fb = (adjacency[ROOM_A, NEAR], adjacency[NEAR, FAR_SIDE],
                  adjacency[FAR_SIDE, ROOM_B])
    g_an, g_nf, g_fb = gap[ROOM_A, NEAR], gap[NEAR, FAR_SIDE], gap[FAR_SIDE, ROOM_B]
    chain_a = jnp.where(ab, g_an, inf)  # near -> a
    chain_b = jnp.where(nf & fb, g_nf + g_fb, inf)  # near -> far -> b
    far_b = jnp.where(fb, g_fb, inf)
    far_a = jnp.where(nf & ab, g_nf + g_an, inf)
    spawn = jnp.where(adjacency[SPAWN_ROWS, room_of_spawn], gap[SPAWN_ROWS, room_of_spawn], inf)
    pair = lambda x, y: jnp.stack([jnp.asarray(x), jnp.asarray(y)], -1)  # noqa: E731
    none = jnp.full(SLOTS * SPAWNS, inf)
    hub = jnp.concatenate([pair(centres, centres), pair(ROOM_A, ROOM_B),
                           pair(ROOM_B, ROOM_A), pair(room_of_spawn, room_of_spawn)]
                          ).astype(jnp.int32)
    offset = jnp.concatenate([pair(jnp.zeros(CELLS), jnp.full(CELLS, inf)),
                              pair(chain_a, chain_b), pair(far_b, far_a), pair(spawn, none)])
    hops = jnp.asarray(np.concatenate([np.tile([0, 0], (CELLS, 1)), np.tile([1, 2], (DOORS, 1)),
                                       np.tile([1, 2], (DOORS, 1)),
                                       np.tile([1, 1], (SLOTS * SPAWNS, 1))]), jnp.int32)
    first = jnp.concatenate([pair(centres, centres), pair(ROOM_A, FAR_SIDE),
                             pair(ROOM_B, NEAR), pair(room_of_spawn, room_of_spawn)]
                            ).astype(jnp.int32)
    entry = jnp.asarray(np.concatenate([np.stack([centres, centres], -1),
                                        np.stack([NEAR, FAR_SIDE], -1),
                                        np.stack([FAR_SIDE, NEAR], -1),
                                        np.stack([SPAWN_ROWS, SPAWN_ROWS], -1)]), jnp.int32)
    return hub, offset, hops, first, entry


def _pair_values(table: Array, hub: Array, offset: Array) -> list[tuple[Array, Array, int, int]]:
    """Every ``(i, j)`` through each pair of attachments ``(p, q)``: ``[(length [N, N], payload
    [N, N], p, q)]``, ``table [R, R, 2]`` holding each pair of rooms' length and payload (one
    gather gives both). A second attachment exists for approach nodes alone, so its blocks are
    gathered for their rows (columns) and the rest is ``inf``."""
    lo, hi = FIRST_APPROACH, FIRST_SPAWN

    def block(rows: np.ndarray, p: int, cols: np.ndarray, q: int) -> tuple[Array, Array]:
        pair = table[hub[rows, p][:, None], hub[cols, q][None, :]]  # [r, c, 2]
        return offset[rows, p][:, None] + pair[..., 0] + offset[cols, q][None, :], pair[..., 1]

    def padded(x: tuple[Array, Array], rows: bool, cols: bool) -> tuple[Array, Array]:
        widths = ((lo, NODES - hi) if rows else (0, 0), (lo, NODES - hi) if cols else (0, 0))
        return (jnp.pad(x[0], widths, constant_values=jnp.inf),
                jnp.pad(x[1], widths, constant_values=0.0))

    every, inner = np.arange(NODES), np.arange(lo, hi)
    return [(*block(every, 0, every, 0), 0, 0),
            (*padded(block(every, 0, inner, 1), False, True), 0, 1),
            (*padded(block(inner, 1, every, 0), True, False), 1, 0),
            (*padded(block(inner, 1, inner, 1), True, True), 1, 1)]


# the two approach nodes of one door (a chain's direct leg), as a constant [N, N] mask
PARTNER = np.concatenate([np.arange(CELLS), FAR_SIDE, NEAR, SPAWN_ROWS])
CHAIN = IS_APPROACH[:, None] & (PARTNER[:, None] == np.arange(NODES)[None, :])


def floorplan_routes(gap: Array, adjacency: Array, edges: Array
                     ) -> tuple[Array, Array, Array, Array]:
    """``(dist [N, N], next_hop [N, N], hops [N, N], fits)`` of a floor plan's graph (``gap``:
    the nodes' distances, m; ``adjacency``: its valid edges; ``edges``: its edge rows, for the
    spawns' rooms), as :func:`sgjax.maps.generated.graph.shortest_paths` gives them (``dist``
    ``inf`` and ``next_hop`` ``NO_PATH`` where unreachable) with ``hops``, the node hops of
    each route (``-1`` where unreachable); ``fits`` is always True (every floor plan has this
    structure). The ``[N, N]`` work is a few gathers from the rooms' ``[16, 16]`` tables and
    elementwise selects (the arrays, not the arithmetic, bound it)."""
    hub, offset, node_hops, first, entry = attachments(gap, adjacency, edges)
    door_length = jnp.where(adjacency[ROOM_A, NEAR] & adjacency[NEAR, FAR_SIDE]
                            & adjacency[FAR_SIDE, ROOM_B],
                            gap[ROOM_A, NEAR] + gap[NEAR, FAR_SIDE] + gap[FAR_SIDE, ROOM_B],
                            jnp.inf)
    length = jnp.full((CELLS, CELLS), jnp.inf).at[ROOM_A, ROOM_B].set(door_length)
    length = length.at[ROOM_B, ROOM_A].set(door_length)
    rooms, next_room = relaxed(length, jnp.isfinite(length),
                               jnp.arange(CELLS, dtype=jnp.int32))
    # per pair of rooms: the node a route from the first enters its next door by, and its
    # room hops, packed in one table (one gather per node pair)
    door_step = jnp.asarray(ENTRY_STEP)[jnp.arange(CELLS)[:, None], jnp.maximum(next_room, 0)]
    packed = (door_step * 16 + room_hops(next_room)).astype(jnp.float32)  # exact in float32
    # the best pair of attachments, and its rooms' payload
    values = _pair_values(jnp.stack([rooms, packed], -1), hub, offset)
    dist, payload, _, _ = values[0]
    second_i, second_j = jnp.zeros((), bool), jnp.zeros((), bool)
    for value, pays, p, q in values[1:]:
        better = value < dist
        dist = jnp.where(better, value, dist)
        payload = jnp.where(better, pays, payload)
        second_i = jnp.where(better, bool(p), second_i)
        second_j = jnp.where(better, bool(q), second_j)
    pick_i = lambda x: jnp.where(second_i, x[:, 1][:, None], x[:, 0][:, None])  # noqa: E731
    pick_j = lambda x: jnp.where(second_j, x[:, 1][None, :], x[:, 0][None, :])  # noqa: E731
    pair = payload.astype(jnp.int32)
    index = jnp.arange(NODES, dtype=jnp.int32)
    # the next node: off a centre (the first rows), the door towards the next room, or the
    # last step into j from this room (a route within one room has no room hops); off any
    # other node, the first on the way to the room it leaves by
    centre_pair = pair[:CELLS]
    from_centre = jnp.where(centre_pair % 16 == 0, pick_j(entry)[:CELLS], centre_pair // 16)
    step = jnp.concatenate([from_centre, pick_i(first)[CELLS:]])
    hops = pick_i(node_hops) + 3 * (pair % 16) + pick_j(node_hops)
    # the two approach nodes of one door: their own edge (48 pairs, set apart)
    rows, cols = np.nonzero(CHAIN)
    direct = adjacency[rows, cols] & (gap[rows, cols] <= dist[rows, cols])
    dist = dist.at[rows, cols].set(jnp.where(direct, gap[rows, cols], dist[rows, cols]))
    step = step.at[rows, cols].set(jnp.where(direct, cols, step[rows, cols]))
    hops = hops.at[rows, cols].set(jnp.where(direct, 1, hops[rows, cols]))
    eye = jnp.asarray(np.eye(NODES, dtype=bool))
    reachable = jnp.isfinite(dist)
    next_hop = jnp.where(eye, index[:, None], jnp.where(reachable, step, NO_PATH))
    hops = jnp.where(eye, 0, jnp.where(reachable, hops, -1))
    return jnp.where(eye, 0.0, dist), next_hop, hops.astype(jnp.int32), jnp.asarray(True)
