"""Whether a generated world is valid, decided inside ``jit``: what ``sgjax maps check`` refuses
in a loaded map (nodes too close to walls, edges through walls, start-goal pairs without a
path), and what a family promises (passages wider than the widest robot, a social dilemma)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from jax import Array

from sgjax.kernels.geometry import (
    point_segment_distance,
    polynomial_atan2,
    segments_intersect_pairs,
)
from sgjax.maps.generated.world import World
from sgjax.maps.schema import DEFAULT_CLEARANCE

PASSAGE_MARGIN = 0.1  # m: a passage must be wider than the widest robot by this much
# Two routes cross a zone in conflicting directions when their headings through it differ by
# more than this angle (opposed flows, crossing flows; not one lane).
CONFLICT_ANGLE = float(np.deg2rad(60.0))
HEADING_BINS = 32  # sectors of 11.25 degrees (one bit each in a uint32)
# Routes of up to this many hops are walked hop by hop (a gather per hop: cheapest for the
# mini-games' routes of 3 to 7 hops); longer ones (the floor plans') by pointer doubling.
WALK_HOPS = 8


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
    """``[E]`` bool: the valid graph edges that cross a valid wall."""
    n = world.nodes
    segments = jnp.concatenate([n[world.edges[:, 0]], n[world.edges[:, 1]]], -1)  # [E, 4]
    cross = segments_intersect_pairs(segments[:, None, :], world.walls[None, :, :], xp=jnp)
    return world.edge_valid & jnp.any(cross & world.wall_valid[None, :], axis=-1)


def group_pairs(world: World) -> Array:
    """``[N, N]`` bool: the (start, goal) pairs some group allows (valid nodes, start !=
    goal)."""
    starts = world.group_starts & world.node_valid[None, :]
    goals = world.group_goals & world.node_valid[None, :]
    count = world.nodes.shape[0]
    return jnp.any(starts[:, :, None] & goals[:, None, :], axis=0) & ~jnp.eye(count, dtype=bool)


def route_steps(next_hop: Array, hops: int) -> list[tuple[Array, Array]]:
    """Every (start, goal) route walked along ``next_hop`` for ``hops`` hops: for each,
    ``(at, hop) [N, N]`` (indexed ``[start, goal]``: where the route is, and the node it moves
    to; a route that has arrived stays put)."""
    count = next_hop.shape[0]
    at = jnp.broadcast_to(jnp.arange(count)[:, None], (count, count))
    goal = jnp.broadcast_to(jnp.arange(count)[None, :], (count, count))
    steps = []
    for _ in range(hops):
        hop = jnp.maximum(next_hop[at, goal], 0)
        steps.append((at, hop))
        at = hop
    return steps


def hop_doublings(next_hop: Array, hops: int) -> list[Array]:
    """Where every (start, goal) route is after 1, 2, 4, ... hops along ``next_hop``: ``[N, N]``
    arrays indexed ``[start, goal]``, enough of them to reach ``hops`` (a route that has
    arrived stays put). Each is the one before composed with itself (pointer doubling), so a
    route of ``L`` nodes costs ``log2 L`` gathers, not ``L``."""
    count = next_hop.shape[0]
    goal = jnp.broadcast_to(jnp.arange(count)[None, :], (count, count))
    at = jnp.maximum(next_hop, 0)  # after one hop (an unreachable goal: node 0, flagged apart)
    powers = [at]
    while (1 << len(powers)) <= hops:
        at = at[at, goal]
        powers.append(at)
    return powers


def after_hops(next_hop: Array, hops: int) -> Array:
    """``[N, N]`` where every (start, goal) route is after exactly ``hops`` hops: walked, or
    composed from :func:`hop_doublings` for routes longer than :data:`WALK_HOPS`."""
    count = next_hop.shape[0]
    at = jnp.broadcast_to(jnp.arange(count)[:, None], (count, count))
    if hops <= WALK_HOPS:
        return route_steps(next_hop, hops)[-1][1] if hops else at
    goal = jnp.broadcast_to(jnp.arange(count)[None, :], (count, count))
    for bit, power in enumerate(hop_doublings(next_hop, hops)):
        if hops >> bit & 1:
            at = power[at, goal]
    return at


def pairs_connected(world: World, dist: Array) -> Array:
    """Whether every (start, goal) pair of every group (start != goal) has a path."""
    return jnp.all(~group_pairs(world) | jnp.isfinite(dist))


def routes_fit(world: World, next_hop: Array, route_nodes: int, hops: Array | None = None
               ) -> Array:
    """Whether every group route reaches its goal within ``route_nodes`` nodes (the route
    arrays' static length: a longer one would be cut short): its hops read from ``hops [N,
    N]`` where the routes came with them (a family's own ``routes``), else the route walked
    along ``next_hop``."""
    if hops is not None:
        return jnp.all(~group_pairs(world) | ((hops >= 0) & (hops <= route_nodes - 1)))
    count = next_hop.shape[0]
    goal = jnp.broadcast_to(jnp.arange(count)[None, :], (count, count))
    last = after_hops(next_hop, route_nodes - 1)
    return jnp.all(~group_pairs(world) | (last == goal))


def used_edges(world: World, next_hop: Array, route_nodes: int) -> Array:
    """``[N, N]`` bool: the directed edges ``i -> j`` some group route takes (every start to
    every goal of its group, along ``next_hop``, for ``route_nodes - 1`` hops or more, the next
    power of two: a longer route fails :func:`routes_fit` anyway). Found by pointer doubling:
    ``on[i, g]``, some route to ``g`` passes ``i`` within its first ``2^k`` hops, grows by
    or-ing ``on`` into the nodes ``2^k`` hops on (a scatter per doubling), so a route of ``L``
    nodes costs ``log2 L`` scatters, not ``L`` gathers of every zone."""
    count = next_hop.shape[0]
    start = jnp.broadcast_to(jnp.arange(count)[:, None], (count, count))
    goal = jnp.broadcast_to(jnp.arange(count)[None, :], (count, count))
    powers = hop_doublings(next_hop, route_nodes - 1)
    on = group_pairs(world)  # [node, goal]: the routes' first nodes
    for power in powers:
        on = on.at[power, goal].max(on)
    hop = powers[0]
    return jnp.zeros((count, count), bool).at[start, hop].max(on & (hop != start))


def zone_headings(world: World, next_hop: Array, route_nodes: int) -> Array:
    """``[Z]`` uint32: for each valid conflict zone, a bit per heading sector
    (:data:`HEADING_BINS` of them) that some group route takes through it, an edge counting in
    a zone where its midpoint lies inside it; the bits are OR-reduced, so no scatter runs per
    zone. Routes of up to :data:`WALK_HOPS` hops are walked (each hop's codes gathered for
    every route); longer ones mark the edges they use first (:func:`used_edges`)."""
    x, y = world.nodes[:, 0], world.nodes[:, 1]
    z = world.zones
    count = x.shape[0]
    mx, my = (x[:, None] + x[None, :]) / 2, (y[:, None] + y[None, :]) / 2  # edge midpoints
    inside = ((mx[None] >= z[:, 0, None, None]) & (mx[None] <= z[:, 2, None, None])
              & (my[None] >= z[:, 1, None, None]) & (my[None] <= z[:, 3, None, None])
              & world.zone_valid[:, None, None])
    angle = polynomial_atan2(y[None, :] - y[:, None], x[None, :] - x[:, None])  # edge i -> j
    sector = (jnp.floor((angle + jnp.pi) / (2 * jnp.pi) * HEADING_BINS).astype(jnp.uint32)
              % HEADING_BINS)
    code = jnp.where(inside, jnp.uint32(1) << sector[None], jnp.uint32(0))  # [Z, N, N]
    if route_nodes - 1 > WALK_HOPS:
        code = jnp.where(used_edges(world, next_hop, route_nodes)[None], code, jnp.uint32(0))
        return jax.lax.reduce(code, jnp.uint32(0), jax.lax.bitwise_or, (1, 2))
    flat = code.reshape(z.shape[0], -1)
    pairs = group_pairs(world)
    bits = jnp.zeros(z.shape[0], jnp.uint32)
    for at, hop in route_steps(next_hop, route_nodes - 1):
        taken = jnp.where(pairs[None] & (hop != at)[None],
                          jnp.take(flat, at * count + hop, axis=1), jnp.uint32(0))
        bits = bits | jax.lax.reduce(taken, jnp.uint32(0), jax.lax.bitwise_or, (1, 2))
    return bits


def conflicting_routes(world: World, next_hop: Array, route_nodes: int) -> Array:
    """``[Z]`` bool: whether two routes cross each conflict zone in conflicting directions:
    two of its heading sectors (:func:`zone_headings`) more than :data:`CONFLICT_ANGLE` apart
    (centre to centre, so within a sector's width of it): opposed or crossing flows through
    the zone, not one lane (robots converging on its entrance from many sides still pass it
    one way)."""
    bits = zone_headings(world, next_hop, route_nodes)
    sector = 2 * np.pi / HEADING_BINS
    found = jnp.zeros(bits.shape, bool)
    for b in range(HEADING_BINS):  # sector b, and any sector far enough from it
        far = sum(1 << c for c in range(HEADING_BINS)
                  if abs(np.angle(np.exp(1j * (b - c) * sector))) > CONFLICT_ANGLE)
        found = found | ((((bits >> b) & 1) == 1) & ((bits & jnp.uint32(far)) != 0))
    return found


def verdict(world: World, dist: Array, next_hop: Array, overflow: Array,
            robot_radius: float, clearance: float = DEFAULT_CLEARANCE,
            route_nodes: int | None = None, check_dilemma: bool = True,
            hops: Array | None = None) -> Verdict:
    """Every check of one world (robots of up to ``robot_radius`` m; nodes at least
    ``clearance`` m from walls, the map checker's rule; routes of at most ``route_nodes``
    nodes, default the node count). ``check_dilemma`` False skips the dilemma check (its
    verdict reads True): a reset does, since a family promises its dilemma by construction
    (tested over thousands of worlds) and the check costs more than the rest together.
    ``hops [N, N]``: the routes' node hops where the family's own routes give them
    (:func:`routes_fit`)."""
    route_nodes = route_nodes or world.nodes.shape[0]
    ok_nodes = jnp.all(~world.node_valid | (node_clearance(world) >= clearance))
    dilemma = (~world.dilemma | jnp.any(conflicting_routes(world, next_hop, route_nodes))
               if check_dilemma else jnp.asarray(True))
    return Verdict(
        made=world.made, clearance=ok_nodes, edges_clear=~jnp.any(edges_through_walls(world)),
        connected=pairs_connected(world, dist),
        routes_fit=routes_fit(world, next_hop, route_nodes, hops),
        passages=jnp.all(~world.zone_valid
                         | (world.zone_width >= 2.0 * robot_radius + PASSAGE_MARGIN)),
        grid=~overflow, dilemma=dilemma)
