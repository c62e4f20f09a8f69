"""A generated world: walls, navigation graph, spawn groups and conflict zones in static
capacities with masks (the leaf type every family builds and :func:`world_arrays` compiles)."""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.maps.arrays import FAR


@dataclasses.dataclass(frozen=True)
class Capacity:
    """A family's static sizes: what every world of it fits in.

    ``walls`` counts the slots including the last one, always a masked padding wall far away
    (the planner's per-cell wall lists point at it for their empty entries); ``extent`` is the
    largest ``(xmin, ymin, xmax, ymax)`` any world of the family can reach (m), which fixes the
    planner's wall grid; ``route_nodes`` bounds the nodes of any start-goal route;
    ``cell_walls`` the walls one grid cell may list (all the wall slots: one cell listing every
    wall, no grid to compute; the planner masks the unused ones). Shortest paths only go
    through nodes of degree 2 or more, so routes are found over the ``hubs`` of them alone
    (Floyd-Warshall over ``hubs`` nodes, not all)."""

    walls: int
    nodes: int
    edges: int
    hubs: int  # nodes that may lie inside a route (degree 2 or more); the rest are leaves
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
    ``node_valid [N]``; ``edges [E, 2]`` node rows of the undirected graph edges,
    ``edge_valid [E]`` (an edge at an invalid node is never valid); ``group_starts``,
    ``group_goals [G, N]``; ``zones [Z, 4]`` conflict-zone rectangles ``(xmin, ymin, xmax,
    ymax)``, ``zone_width [Z]`` the free width of the passage each guards (m) and
    ``zone_valid [Z]`` (a padding zone lies far away, its width far wider than any robot); ``bounds
    [4]`` the drawing extent; ``made`` whether the draw could build the world at all (False:
    flagged, never looped on); ``dilemma`` whether the family promises a social dilemma in this
    world."""

    walls: Array
    wall_valid: Array
    nodes: Array
    node_valid: Array
    edges: Array
    edge_valid: Array
    group_starts: Array
    group_goals: Array
    zones: Array
    zone_width: Array
    zone_valid: Array
    bounds: Array
    made: Array
    dilemma: Array

    @property
    def adjacency(self) -> Array:
        """``[N, N]`` bool: the valid edges, both ways."""
        count = self.nodes.shape[0]
        keep = (self.edge_valid & self.node_valid[self.edges[:, 0]]
                & self.node_valid[self.edges[:, 1]])
        adjacency = jnp.zeros((count, count), bool)
        adjacency = adjacency.at[self.edges[:, 0], self.edges[:, 1]].max(keep)
        return adjacency.at[self.edges[:, 1], self.edges[:, 0]].max(keep)


def padded_walls(walls: Array, capacity: int, built: Array | None = None
                 ) -> tuple[Array, Array]:
    """``walls [K, 4]`` in ``capacity`` slots (the rest, the last always, padding far away):
    ``(walls [capacity, 4], valid [capacity])``, valid where ``built [K]`` (default all)."""
    count = walls.shape[0]
    if count >= capacity:
        raise ValueError(f"{count} walls need {count + 1} slots (one is padding); the "
                         f"capacity is {capacity}")
    pad = jnp.broadcast_to(jnp.asarray([FAR, FAR, FAR + 1.0, FAR], walls.dtype),
                           (capacity - count, 4))
    valid = jnp.arange(capacity) < count
    if built is not None:
        valid = valid & jnp.concatenate([built, jnp.zeros(capacity - count, bool)])
    return jnp.concatenate([walls, pad]), valid
