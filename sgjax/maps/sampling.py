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


def _pick(key: Array, mask: Array) -> tuple[Array, Array]:
    """Uniform index among the True entries of ``mask``; ``ok`` is False if there are none."""
    count = jnp.sum(mask)
    target = jnp.floor(jax.random.uniform(key) * count)
    index = jnp.argmax(jnp.cumsum(mask) > target)
    return index.astype(jnp.int32), count > 0


def _pick_weighted(key: Array, weights: Array) -> tuple[Array, Array]:
    """Index drawn with probability proportional to non-negative ``weights``."""
    total = jnp.sum(weights)
    target = jax.random.uniform(key) * total
    index = jnp.argmax(jnp.cumsum(weights) > target)
    return index.astype(jnp.int32), total > 0


def sample_starts_goals(
    key: Array, m: MapArrays, radius: Array, wanted: Array
) -> tuple[Array, Array, Array]:
    """Draw a (start, goal) node pair for every wanted robot slot.

    A group is drawn with weight (free starts x free goals), then a start and a goal uniformly in
    it. No two robots share a start or a goal, and the bodies at the starts do not overlap
    (centres at least ``r_i + r_j + START_MARGIN`` apart). ``radius`` and ``wanted`` are ``[R]``.
    Returns ``start, goal`` node rows ``[R]`` and ``placed [R]`` (False where no pair was left).
    """
    num_robots = radius.shape[0]
    num_nodes = m.node_x.shape[0]

    def place(carry, inputs):
        start_free, goal_free, starts, placed = carry
        key_i, r_i, wanted_i, i = inputs
        k_group, k_start, k_goal = jax.random.split(key_i, 3)
        other_gap = m.node_gap[:, starts]  # [N, R]: node to every placed start
        clear = jnp.all(~placed[None, :] | (other_gap >= r_i + radius[None, :] + START_MARGIN), 1)
        ok_start = start_free & clear
        n_starts = jnp.sum(m.group_starts & ok_start[None, :], axis=1)
        n_goals = jnp.sum(m.group_goals & goal_free[None, :], axis=1)
        group, ok_g = _pick_weighted(k_group, (n_starts * n_goals).astype(jnp.float32))
        start, ok_s = _pick(k_start, m.group_starts[group] & ok_start)
        goal_mask = m.group_goals[group] & goal_free & (jnp.arange(num_nodes) != start)
        goal, ok_t = _pick(k_goal, goal_mask)
        success = wanted_i & ok_g & ok_s & ok_t
        start_free = start_free.at[start].set(start_free[start] & ~success)
        goal_free = goal_free.at[goal].set(goal_free[goal] & ~success)
        starts = starts.at[i].set(jnp.where(success, start, 0))
        placed = placed.at[i].set(success)
        return (start_free, goal_free, starts, placed), (start, goal, success)

    init = (
        jnp.ones(num_nodes, bool),
        jnp.ones(num_nodes, bool),
        jnp.zeros(num_robots, jnp.int32),
        jnp.zeros(num_robots, bool),
    )
    keys = jax.random.split(key, num_robots)
    _, (start, goal, placed) = jax.lax.scan(
        place, init, (keys, radius, wanted, jnp.arange(num_robots))
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
