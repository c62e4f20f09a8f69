"""Scenario sampling inside ``reset`` (jittable): starts, goals and the routes between them."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.maps.arrays import MapArrays

START_MARGIN = 0.02  # m of free space between the bodies of two robots placed at their starts


@struct.dataclass
class Route:
    """Each robot's waypoints along the shortest graph path from its start to its goal.

    ``x``, ``y``, ``cum_length`` are ``[R, L]`` (m); entries past ``num_nodes - 1`` repeat the goal.
    """

    x: Array
    y: Array
    cum_length: Array
    num_nodes: Array  # [R] int32
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


def _mix32(h: Array) -> Array:
    """MurmurHash3's 32-bit finaliser: a cheap bijective scramble of uint32 values."""
    h = h ^ (h >> 16)
    h = h * jnp.uint32(0x85EBCA6B)
    h = h ^ (h >> 13)
    h = h * jnp.uint32(0xC2B2AE35)
    return h ^ (h >> 16)


def _pick_by_priority(priority: Array, mask: Array) -> tuple[Array, Array]:
    """Index of the highest-priority True entry of ``mask`` (max and min reductions only: XLA's
    CPU cumsum and argmax are slow under vmap). ``priority`` is uint32 and never 0."""
    masked = jnp.where(mask, priority, jnp.uint32(0))
    best = jnp.max(masked)
    index = jnp.min(jnp.where(masked == best, jnp.arange(mask.shape[0]), mask.shape[0]))
    return jnp.minimum(index, mask.shape[0] - 1).astype(jnp.int32), best > 0


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
    free goal of that group with the highest random priority (a uniform choice among them; every
    slot re-scrambles one threefry draw of node priorities with MurmurHash3's finaliser). No two
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
    key_nodes, key_groups = jax.random.split(key)
    node_bits = jax.random.bits(key_nodes, (2, num_nodes), jnp.uint32)
    group_draws = jax.random.uniform(key_groups, (num_robots,))
    salts = (jnp.arange(num_robots, dtype=jnp.uint32) + 1) * jnp.uint32(0x9E3779B9)

    def place(carry, inputs):
        # One-hot selections instead of gathers and scatters: faster under vmap on the CPU.
        start_free, goal_free = carry
        u, salt, reach_i, wanted_i = inputs
        priority = _mix32(node_bits ^ salt) | jnp.uint32(1)
        n_starts = jnp.sum(m.group_starts & start_free[None, :], axis=1)
        n_goals = jnp.sum(m.group_goals & goal_free[None, :], axis=1)
        group, ok_g = _pick_weighted(u, (n_starts * n_goals).astype(jnp.float32))
        in_group = (group_index == group)[:, None]
        group_starts = jnp.any(m.group_starts & in_group, axis=0)
        group_goals = jnp.any(m.group_goals & in_group, axis=0)
        start, ok_s = _pick_by_priority(priority[0], group_starts & start_free)
        is_start = node_index == start
        goal, ok_t = _pick_by_priority(priority[1], group_goals & goal_free & ~is_start)
        success = wanted_i & ok_g & ok_s & ok_t
        start_free = start_free & ~(success & (m.node_gap[start] < reach_i))
        goal_free = goal_free & ~(success & (node_index == goal))
        return (start_free, goal_free), (start, goal, success)

    init = (jnp.ones(num_nodes, bool), jnp.ones(num_nodes, bool))
    _, (start, goal, placed) = jax.lax.scan(
        place, init, (group_draws, salts, reach, wanted)
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
    num_nodes = 1 + jnp.sum(path[:, 1:] != path[:, :-1], axis=1)
    return Route(x=x, y=y, cum_length=cum, num_nodes=num_nodes.astype(jnp.int32),
                 start=start, goal=goal)
