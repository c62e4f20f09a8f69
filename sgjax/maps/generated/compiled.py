"""A generated world compiled to :class:`~sgjax.maps.arrays.MapArrays` inside ``jit``: the same
arrays ``compile_map`` makes of a loaded map, so every term, metric, baseline, renderer and the
trainer work on it unchanged."""

from __future__ import annotations

from collections.abc import Callable

import jax.numpy as jnp
from jax import Array

from sgjax.maps.arrays import MapArrays
from sgjax.maps.generated.graph import shortest_paths
from sgjax.maps.generated.grid import cell_walls, grid_layout
from sgjax.maps.generated.world import Capacity, World


def world_arrays(world: World, capacity: Capacity, routes: Callable | None = None
                 ) -> tuple[MapArrays, Array, Array, Array | None]:
    """``(arrays, dist [N, N], overflow, hops)``: the world's map arrays, its shortest-path
    lengths (``inf`` where unreachable, for the checks), whether it overflows its family's
    capacity (more walls near a cell than a cell lists, more route nodes than ``hubs``) and
    the node hops of every route (``[N, N]``, from a family's own ``routes``, see
    :class:`~sgjax.maps.generated.family.Family`; None from the generic Floyd-Warshall)."""
    nodes = world.nodes
    gap = jnp.linalg.norm(nodes[:, None, :] - nodes[None, :, :], axis=-1)
    if routes is None:
        dist, next_hop, fits = shortest_paths(gap, world.adjacency, capacity.hubs)
        hops = None
    else:
        dist, next_hop, hops, fits = routes(gap, world.adjacency, world.edges)
    lists, overflow = cell_walls(world.walls, world.wall_valid, capacity)
    overflow = overflow | ~fits
    origin, shape = grid_layout(capacity)
    # padding nodes are never starts or goals, and lie far from everything
    arrays = MapArrays(
        wall_x1=world.walls[:, 0], wall_y1=world.walls[:, 1],
        wall_x2=world.walls[:, 2], wall_y2=world.walls[:, 3], wall_valid=world.wall_valid,
        node_x=nodes[:, 0], node_y=nodes[:, 1], next_hop=next_hop,
        path_length=jnp.where(jnp.isfinite(dist), dist, -1.0),
        group_starts=world.group_starts & world.node_valid[None, :],
        group_goals=world.group_goals & world.node_valid[None, :],
        node_gap=gap, cell_walls=lists, grid_origin=jnp.asarray(origin, jnp.float32),
        zone_rect=world.zones, zone_width=world.zone_width,
        max_route_nodes=capacity.route_nodes, grid_shape=shape,
        cell_size=float(capacity.cell_size), reach=float(capacity.reach))
    return arrays, dist, overflow, hops
