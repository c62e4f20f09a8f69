"""Two rooms joined by a passage through the wall between them: the doorway (a short passage,
the wall's thickness) and the hallway (a long corridor, optionally with a lay-by niche on one
side). Robots start in either room and cross to the other (two flows meeting in the passage:
the social dilemma), or, in a one-way world (the families' ``ways`` parameter below 1.5),
all start in the left room and cross to the right (one flow queueing at a bottleneck, as
SocialGym 2.0's doorway has it: no dilemma is promised then)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array

from sgjax.maps.generated.lattice import lattice
from sgjax.maps.generated.world import Capacity, World, padded_walls

SPAWN_COLUMNS, SPAWN_ROWS = 3, 8  # spawn lattice of each room
SPAWNS = SPAWN_COLUMNS * SPAWN_ROWS
APPROACH = 1.5  # m: the passage's approach nodes stand this far from its mouths
SPAWN_GAP = 0.5  # m: spawns keep this far behind the approach node
MARGIN = 0.6  # m: spawns keep this far from the room's walls
ZONE_MARGIN = 0.5  # m: the conflict zone reaches this far past the passage's sides
LAYBY_MIN = 0.4  # m: a lay-by shallower than this is not built
NODES = 2 + 2 * SPAWNS
EDGES = 1 + 2 * SPAWNS  # the passage, and each spawn to its room's approach node
ONE_WAY_BELOW = 1.5  # a ``ways`` value below this is a one-way world
WALLS = 17  # 16 wall slots (4 of them the lay-by's and the corridor wall past it) + padding


def two_rooms(key: Array, capacity: Capacity, room_height: Array, left_depth: Array,
              right_depth: Array, length: Array, width: Array, offset: Array,
              layby_depth: Array | None = None, layby_at: Array | None = None,
              layby_length: Array | None = None, ways: Array | None = None) -> World:
    """The world: rooms ``left_depth`` and ``right_depth`` deep (m, along x) and ``room_height``
    tall, the passage ``length`` long and ``width`` wide, its centre line ``offset`` (a
    fraction in [-1, 1] of the room's room for it) off the rooms' middle; with a lay-by
    ``layby_depth`` deep (m, into the upper corridor wall; none below :data:`LAYBY_MIN`),
    ``layby_length`` long, its centre at ``layby_at`` (a fraction of the corridor) along it;
    ``ways`` below 1.5: one way (both spawn groups left to right), else (or None) both ways."""
    h, half, g = room_height / 2, length / 2, width / 2
    o = offset * jnp.maximum(h - g - 1.0, 0.0)
    x0, x1 = -half - left_depth, half + right_depth
    top, bottom = o + g, o - g
    if layby_depth is None:  # no lay-by: its walls are never built
        layby_depth, layby_at, layby_length = jnp.float32(0.0), jnp.float32(0.5), jnp.float32(0.0)
    niche = layby_depth >= LAYBY_MIN
    lx = -half + layby_at * length
    la = jnp.clip(lx - layby_length / 2, -half + 0.3, half - 0.3)
    lb = jnp.clip(lx + layby_length / 2, -half + 0.3, half - 0.3)
    up = top + layby_depth
    segments = jnp.stack([
        jnp.stack([x0, -h, -half, -h]), jnp.stack([x0, h, -half, h]), jnp.stack([x0, -h, x0, h]),
        jnp.stack([-half, top, -half, h]), jnp.stack([-half, -h, -half, bottom]),
        # the upper corridor wall: whole, or up to the lay-by and on from it
        jnp.stack([-half, top, jnp.where(niche, la, half), top]),
        jnp.stack([lb, top, half, top]),
        jnp.stack([la, top, la, up]), jnp.stack([la, up, lb, up]), jnp.stack([lb, up, lb, top]),
        jnp.stack([-half, bottom, half, bottom]),
        jnp.stack([half, top, half, h]), jnp.stack([half, -h, half, bottom]),
        jnp.stack([half, -h, x1, -h]), jnp.stack([half, h, x1, h]), jnp.stack([x1, -h, x1, h]),
    ])
    walls, valid = padded_walls(segments, capacity.walls,
                                jnp.ones(len(segments), bool).at[6:10].set(niche))
    a = jnp.stack([-half - APPROACH, o])
    b = jnp.stack([half + APPROACH, o])
    k_left, k_right = jax.random.split(key)
    left = lattice(k_left, jnp.stack([x0, -h, a[0] - SPAWN_GAP + MARGIN, h]), SPAWN_COLUMNS,
                   SPAWN_ROWS, MARGIN)
    right = lattice(k_right, jnp.stack([b[0] + SPAWN_GAP - MARGIN, -h, x1, h]),
                    SPAWN_COLUMNS, SPAWN_ROWS, MARGIN)
    nodes = jnp.concatenate([a[None], b[None], left, right])
    left_rows, right_rows = jnp.arange(2, 2 + SPAWNS), jnp.arange(2 + SPAWNS, NODES)
    pairs = jnp.concatenate([jnp.asarray([[0, 1]]),
                             jnp.stack([jnp.zeros(SPAWNS, jnp.int32), left_rows], 1),
                             jnp.stack([jnp.ones(SPAWNS, jnp.int32), right_rows], 1)])
    in_left = jnp.zeros(NODES, bool).at[left_rows].set(True)
    in_right = jnp.zeros(NODES, bool).at[right_rows].set(True)
    zone = jnp.stack([a[0], bottom - ZONE_MARGIN, b[0], jnp.where(niche, up, top) + ZONE_MARGIN])
    two_way = jnp.asarray(True) if ways is None else ways >= ONE_WAY_BELOW
    starts = jnp.stack([in_left, jnp.where(two_way, in_right, in_left)])
    goals = jnp.stack([in_right, jnp.where(two_way, in_left, in_right)])
    return World(
        walls=walls, wall_valid=valid, nodes=nodes, node_valid=jnp.ones(NODES, bool),
        edges=pairs, edge_valid=jnp.ones(EDGES, bool), group_starts=starts, group_goals=goals,
        zones=zone[None],
        zone_width=width[None], zone_valid=jnp.ones(1, bool),
        bounds=jnp.stack([x0 - 0.5, -h - 0.5, x1 + 0.5, h + 0.5]),
        made=jnp.asarray(True), dilemma=two_way)
