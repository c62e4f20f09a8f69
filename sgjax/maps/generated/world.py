"""A generated world: walls, navigation graph, spawn groups and conflict zones in static
capacities with masks (the leaf type every family builds and :func:`world_arrays` compiles)."""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
from flax import struct
from jax import Array

FAR = 1.0e6  # m: where padding walls and nodes live


@dataclasses.dataclass(frozen=True)
class Capacity:
    """A family's static sizes: what every world of it fits in.

    ``walls`` counts the slots including the last one, always a masked padding wall far away
    (the planner's per-cell wall lists point at it for their empty entries); ``extent`` is the
    largest ``(xmin, ymin, xmax, ymax)`` any world of the family can reach (m), which fixes the
    planner's wall grid; ``route_nodes`` bounds the nodes of any start-goal route;
    ``cell_walls`` the walls one grid cell may list."""

    walls: int
    nodes: int
    groups: int
    zones: int
    route_nodes: int
    extent: tuple[float, float, float, float]
    cell_walls: int
    reach: float = 2.5  # m: how far the planner looks for walls (as compile_map)
    cell_size: float = 1.0  # m


@struct.dataclass
class World:
    """One generated world (a pytree; ``vmap`` gives a batch of them).

    ``walls [W, 4]`` segments ``(x1, y1, x2, y2)`` (m), ``wall_valid [W]``; ``nodes [N, 2]`` (m),
    ``node_valid [N]``; ``adjacency [N, N]`` the undirected graph edges (symmetric, none on the
    diagonal or at invalid nodes); ``group_starts``, ``group_goals [G, N]``; ``zones [Z, 4]``
    conflict-zone rectangles ``(xmin, ymin, xmax, ymax)`` and ``zone_width [Z]`` the free width
    of the passage each guards (m); ``bounds [4]`` the drawing extent; ``made`` whether the
    draw could build the world at all (False: flagged, never looped on); ``dilemma`` whether
    the family promises a social dilemma in this world."""

    walls: Array
    wall_valid: Array
    nodes: Array
    node_valid: Array
    adjacency: Array
    group_starts: Array
    group_goals: Array
    zones: Array
    zone_width: Array
    bounds: Array
    made: Array
    dilemma: Array


def padded_walls(walls: Array, capacity: int) -> tuple[Array, Array]:
    """``walls [K, 4]`` in ``capacity`` slots (the rest, the last always, padding far away):
    ``(walls [capacity, 4], valid [capacity])``."""
    count = walls.shape[0]
    if count >= capacity:
        raise ValueError(f"{count} walls need {count + 1} slots (one is padding); the "
                         f"capacity is {capacity}")
    pad = jnp.broadcast_to(jnp.asarray([FAR, FAR, FAR + 1.0, FAR], walls.dtype),
                           (capacity - count, 4))
    valid = jnp.arange(capacity) < count
    return jnp.concatenate([walls, pad]), valid


def undirected(count: int, pairs: list[tuple[int, int]] | Array, mask: Array | None = None
               ) -> Array:
    """``[count, count]`` bool adjacency of the edge ``pairs`` (rows ``[E, 2]``), both ways,
    each edge kept where ``mask [E]`` (default all)."""
    pairs = jnp.asarray(pairs, jnp.int32).reshape(-1, 2)
    keep = jnp.ones(pairs.shape[0], bool) if mask is None else mask
    adjacency = jnp.zeros((count, count), bool)
    adjacency = adjacency.at[pairs[:, 0], pairs[:, 1]].max(keep)
    return adjacency.at[pairs[:, 1], pairs[:, 0]].max(keep)
