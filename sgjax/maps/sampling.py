"""Scenario sampling inside ``reset`` (jittable): starts, goals and the routes between them."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.kernels.geometry import safe_norm
from sgjax.maps.arrays import MapArrays

START_MARGIN = 0.02  # m of free space between the bodies of two robots placed at their starts


@struct.dataclass
class Route:
    """Each robot's waypoints along the shortest graph path from its start to its goal.

    ``x``, ``y``, ``cum_length`` are ``[R, L]`` (m); entries past the goal repeat it.
    """

    x: Array
    y: Array
    cum_length: Array
    start: Array  # [R] int32 node rows
    goal: Array  # [R] int32 node rows

    @property
    def goal_x(self) -> Array:
        return self.x[:, -1]

    @property
    def goal_y(self) -> Array:
        return self.y[:, -1]

    @property
    def total_length(self) -> Array:
        return self.cum_length[:, -1]

    def goal_distance(self, x: Array, y: Array) -> Array:
        """``[R]`` straight-line distance (m) from positions ``x, y [R]`` to the goals."""
        return safe_norm(self.goal_x - x, self.goal_y - y)


def mix32(h: Array) -> Array:
    """MurmurHash3's 32-bit finaliser: a cheap bijective scramble of uint32 values."""
    h = h ^ (h >> 16)
    h = h * jnp.uint32(0x85EBCA6B)
    h = h ^ (h >> 13)
    h = h * jnp.uint32(0xC2B2AE35)
    return h ^ (h >> 16)


def _pick_by_priority(priority: Array, mask: Array, index_bits: int) -> tuple[Array, Array]:
    """Index of the highest-priority True entry of ``mask``, in one max reduction.

    ``priority`` (uint32, top bit set) carries each entry's index in its low ``index_bits`` bits,
    so the maximum also names its position (XLA's CPU argmax is slow under vmap). Returns the
    index and whether any entry was True.
    """
    best = jnp.max(jnp.where(mask, priority, jnp.uint32(0)))
    return (best & jnp.uint32((1 << index_bits) - 1)).astype(jnp.int32), best > 0


def _pick_weighted(u: Array, weights: Array) -> tuple[Array, Array]:
    """Index with probability proportional to non-negative ``weights`` ``[G]`` for ``u`` in [0, 1).

    The cumulative sum is a ``[G, G]`` comparison sum (G, the number of groups, is small).
    """
    g = weights.shape[0]
    lower = jnp.arange(g)[None, :] <= jnp.arange(g)[:, None]
    cum = jnp.sum(jnp.where(lower, weights[None, :], 0.0), axis=1)
    total = cum[-1]
    index = jnp.minimum(jnp.sum(cum <= u * total), g - 1)
    return index.astype(jnp.int32), total > 0


def sample_starts_goals(
    key: Array, m: MapArrays, radius: Array, wanted: Array
) -> tuple[Array, Array, Array]:
    """Draw a (start, goal) node pair for every wanted robot slot, one slot after another.

    Each slot draws a group with weight (free starts x free goals), then the free start and the
    free goal of that group with the highest random priority (a uniform choice among them, up to
    ties in the priorities' 25 or more random bits).
    Randomness: one threefry block per reset; every (slot, purpose, node) priority is a
    counter-based hash of it (MurmurHash3's finaliser of seed xor a Weyl sequence), much
    cheaper on the CPU than a threefry draw per node. No two
    robots share a start or a goal, and bodies at the starts do not overlap: placing a robot of
    radius ``r_j`` blocks every start closer than ``r_j + max(radius) + START_MARGIN`` (exact for
    a team of one size, conservative for mixed sizes). ``radius`` and ``wanted`` are ``[R]``.
    Returns ``start, goal`` node rows ``[R]`` and ``placed [R]`` (False where no pair was left).
    """
    num_robots = radius.shape[0]
    num_nodes = m.node_x.shape[0]
    reach = radius + jnp.max(radius) + START_MARGIN
    node_index = jnp.arange(num_nodes)
    group_index = jnp.arange(m.group_starts.shape[0])
    seed = jax.random.bits(key, (2,), jnp.uint32)
    slots = jnp.arange(num_robots, dtype=jnp.uint32)
    group_draws = (mix32(seed[1] ^ mix32(slots + 1)) >> 8).astype(jnp.float32) / 2.0**24
    index_bits = max(1, (num_nodes - 1).bit_length())
    high_bits = jnp.uint32(0xFFFFFFFF ^ ((1 << index_bits) - 1))
    # Every slot's start and goal priorities at once, [R, 2, N], with the node index in the low
    # bits so that one max reduction names the winner.
    counters = jnp.arange(num_robots * 2 * num_nodes, dtype=jnp.uint32).reshape(
        num_robots, 2, num_nodes)
    scrambled = mix32(seed[0] ^ (counters * jnp.uint32(0x9E3779B9))) | jnp.uint32(0x80000000)
    priorities = (scrambled & high_bits) | node_index.astype(jnp.uint32)
    single_group = m.group_starts.shape[0] == 1

    def place(carry, inputs):
        # Reductions over the nodes dominate the cost on the CPU: two per slot (one per pick),
        # plus one to weigh the groups when a map has several.
        start_free, goal_free = carry
        u, priority, reach_i, wanted_i = inputs
        if single_group:
            group_starts, group_goals, ok_g = m.group_starts[0], m.group_goals[0], True
        else:
            free = jnp.stack([m.group_starts & start_free[None, :],
                              m.group_goals & goal_free[None, :]])
            counts = jnp.sum(free, axis=2)  # [2, G]
            group, ok_g = _pick_weighted(u, (counts[0] * counts[1]).astype(jnp.float32))
            in_group = (group_index == group)[:, None]
            group_starts = jnp.any(m.group_starts & in_group, axis=0)
            group_goals = jnp.any(m.group_goals & in_group, axis=0)
        start, ok_s = _pick_by_priority(priority[0], group_starts & start_free, index_bits)
        is_start = node_index == start
        goal, ok_t = _pick_by_priority(priority[1], group_goals & goal_free & ~is_start,
                                       index_bits)
        success = wanted_i & ok_g & ok_s & ok_t
        start_free = start_free & ~(success & (m.node_gap[start] < reach_i))
        goal_free = goal_free & ~(success & (node_index == goal))
        return (start_free, goal_free), (start, goal, success)

    init = (jnp.ones(num_nodes, bool), jnp.ones(num_nodes, bool))
    _, (start, goal, placed) = jax.lax.scan(
        place, init, (group_draws, priorities, reach, wanted), unroll=True
    )
    return start, goal, placed


def build_routes(m: MapArrays, start: Array, goal: Array) -> Route:
    """Expand (start, goal) rows ``[R]`` into waypoint arrays along the shortest graph paths."""
    nodes = [start]
    for _ in range(m.max_route_nodes - 1):
        nodes.append(m.next_hop[nodes[-1], goal])
    path = jnp.stack(nodes, axis=1)  # [R, L]
    x, y = m.node_x[path], m.node_y[path]
    seg = jnp.sqrt(jnp.square(jnp.diff(x, axis=1)) + jnp.square(jnp.diff(y, axis=1)))
    cum = jnp.concatenate([jnp.zeros_like(x[:, :1]), jnp.cumsum(seg, axis=1)], axis=1)
    return Route(x=x, y=y, cum_length=cum, start=start, goal=goal)
