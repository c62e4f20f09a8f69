"""Whether a generated world is valid, decided inside ``jit``: what ``sgjax maps check`` refuses
in a loaded map (nodes too close to walls, edges through walls, start-goal pairs without a
path), and what a family promises (passages wider than the widest robot, a social dilemma)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from flax import struct
from jax import Array

from sgjax.kernels.geometry import point_segment_distance, segments_intersect_pairs
from sgjax.maps.generated.world import World
from sgjax.maps.schema import DEFAULT_CLEARANCE

PASSAGE_MARGIN = 0.1  # m: a passage must be wider than the widest robot by this much
# Two routes cross a zone in conflicting directions when their headings through it differ by
# more than this angle (opposed flows, crossing flows; not one lane).
CONFLICT_ANGLE = float(np.deg2rad(60.0))
HEADING_BINS = 36  # sectors of 10 degrees


@struct.dataclass
class Verdict:
    """Each check of :func:`verdict` (bool scalars) and ``valid``, all of them."""

    made: Array
    clearance: Array
    edges_clear: Array
    connected: Array
    routes_fit: Array
    passages: Array
    grid: Array
    dilemma: Array

    @property
    def valid(self) -> Array:
        return (self.made & self.clearance & self.edges_clear & self.connected
                & self.routes_fit & self.passages & self.grid & self.dilemma)


def node_clearance(world: World) -> Array:
    """``[N]`` each node's distance to the nearest valid wall (m; ``inf`` without walls)."""
    w = world.walls
    dist = point_segment_distance(world.nodes[:, 0:1], world.nodes[:, 1:2], w[:, 0], w[:, 1],
                                  w[:, 2], w[:, 3])
    return jnp.min(jnp.where(world.wall_valid[None, :], dist, jnp.inf), axis=1)


def edges_through_walls(world: World) -> Array:
    """``[N, N]`` bool: the graph edges that cross a valid wall."""
    n = world.nodes
    segments = jnp.concatenate([jnp.broadcast_to(n[:, None, :], (n.shape[0],) * 2 + (2,)),
                                jnp.broadcast_to(n[None, :, :], (n.shape[0],) * 2 + (2,))], -1)
    cross = segments_intersect_pairs(segments[:, :, None, :], world.walls[None, None, :, :],
                                     xp=jnp)
    return world.adjacency & jnp.any(cross & world.wall_valid[None, None, :], axis=-1)


def pairs_connected(world: World, dist: Array) -> Array:
    """Whether every (start, goal) pair of every group (start != goal) has a path."""
    starts = world.group_starts & world.node_valid[None, :]
    goals = world.group_goals & world.node_valid[None, :]
    pair = starts[:, :, None] & goals[:, None, :] & ~jnp.eye(dist.shape[0], dtype=bool)
    return jnp.all(~pair | jnp.isfinite(dist)[None])


def routes_fit(world: World, next_hop: Array, route_nodes: int) -> Array:
    """Whether every group route reaches its goal within ``route_nodes`` nodes (the route
    arrays' static length: a longer one would be cut short)."""
    starts = world.group_starts & world.node_valid[None, :]
    goals = world.group_goals & world.node_valid[None, :]
    count = next_hop.shape[0]
    pairs = jnp.any(starts[:, :, None] & goals[:, None, :], axis=0) & ~jnp.eye(count, dtype=bool)
    at = jnp.broadcast_to(jnp.arange(count)[:, None], (count, count))  # [start, goal]
    goal = jnp.broadcast_to(jnp.arange(count)[None, :], (count, count))
    for _ in range(route_nodes - 1):
        at = jnp.maximum(next_hop[at, goal], 0)
    return jnp.all(~pairs | (at == goal))


def on_routes(world: World, dist: Array) -> Array:
    """``[N, N]`` bool: node ``i`` lies on a shortest route from a start to goal ``j`` of one of
    the world's groups (``dist[s, i] + dist[i, j]`` equals ``dist[s, j]`` up to float
    rounding)."""
    starts = world.group_starts & world.node_valid[None, :]
    goals = world.group_goals & world.node_valid[None, :]
    count = dist.shape[0]
    pairs = jnp.any(starts[:, :, None] & goals[:, None, :], axis=0) & ~jnp.eye(count, dtype=bool)
    reach = jnp.isfinite(dist)
    safe = jnp.where(reach, dist, 0.0)
    via = safe[:, :, None] + safe[None, :, :]  # [s, i, j]
    on = (reach[:, :, None] & reach[None, :, :] & pairs[:, None, :]
          & (via <= safe[:, None, :] * (1.0 + 1e-5) + 1e-5))
    return jnp.any(on, axis=0)


def conflicting_routes(world: World, dist: Array, next_hop: Array) -> Array:
    """``[Z]`` bool: whether two routes cross each conflict zone in conflicting directions.

    A route crosses a zone on each of its edges whose midpoint lies inside it; the edges'
    headings are binned in :data:`HEADING_BINS` sectors, and two occupied sectors more than
    :data:`CONFLICT_ANGLE` apart (centre to centre, so within a sector's width of it) make a
    conflict: opposed or crossing flows through the zone, not one lane (robots converging on
    its entrance from many sides still pass it one way)."""
    x, y = world.nodes[:, 0], world.nodes[:, 1]
    count = x.shape[0]
    z = world.zones
    hop = jnp.maximum(next_hop, 0)  # [N, N]: the edge i -> hop[i, j] towards goal j
    moving = (next_hop >= 0) & (hop != jnp.arange(count)[:, None])
    used = on_routes(world, dist) & moving  # [N, N]
    mx, my = (x[:, None] + x[hop]) / 2, (y[:, None] + y[hop]) / 2  # [N, N] edge midpoints
    touches = ((mx[None] >= z[:, 0, None, None]) & (mx[None] <= z[:, 2, None, None])
               & (my[None] >= z[:, 1, None, None]) & (my[None] <= z[:, 3, None, None]))
    angle = jnp.arctan2(y[hop] - y[:, None], x[hop] - x[:, None])
    sector = (jnp.floor((angle + jnp.pi) / (2 * jnp.pi) * HEADING_BINS).astype(jnp.int32)
              % HEADING_BINS)
    occupied = jnp.zeros((z.shape[0], HEADING_BINS), bool).at[:, sector].max(
        touches & used[None])  # [Z, B]
    centres = (jnp.arange(HEADING_BINS) + 0.5) * (2 * jnp.pi / HEADING_BINS)
    apart = jnp.abs(jnp.angle(jnp.exp(1j * (centres[:, None] - centres[None, :]))))
    return jnp.any(occupied[:, :, None] & occupied[:, None, :] & (apart > CONFLICT_ANGLE)[None],
                   axis=(1, 2))


def verdict(world: World, dist: Array, next_hop: Array, overflow: Array,
            robot_radius: float, clearance: float = DEFAULT_CLEARANCE,
            route_nodes: int | None = None) -> Verdict:
    """Every check of one world (robots of up to ``robot_radius`` m; nodes at least
    ``clearance`` m from walls, the map checker's rule; routes of at most ``route_nodes``
    nodes, default the node count)."""
    ok_nodes = jnp.all(~world.node_valid | (node_clearance(world) >= clearance))
    dilemma = ~world.dilemma | jnp.any(conflicting_routes(world, dist, next_hop))
    return Verdict(
        made=world.made, clearance=ok_nodes, edges_clear=~jnp.any(edges_through_walls(world)),
        connected=pairs_connected(world, dist),
        routes_fit=routes_fit(world, next_hop, route_nodes or world.nodes.shape[0]),
        passages=jnp.all(world.zone_width >= 2.0 * robot_radius + PASSAGE_MARGIN),
        grid=~overflow, dilemma=dilemma)
