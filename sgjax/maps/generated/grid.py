"""The planner's wall grid of a generated world, inside ``jit``: for each cell of a fixed grid
over the family's extent, the walls within reach (``maps.arrays.wall_grid`` is its host
counterpart)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jax import Array

from sgjax.kernels.geometry import point_segment_distance
from sgjax.maps.generated.world import Capacity


def grid_layout(capacity: Capacity) -> tuple[np.ndarray, tuple[int, int]]:
    """``(origin [2], (nx, ny))`` of the family's grid: its extent grown by the reach (one cell
    where the cells list every wall)."""
    lo = np.asarray(capacity.extent[:2], float) - capacity.reach
    if capacity.cell_walls >= capacity.walls - 1:
        return lo, (1, 1)
    hi = np.asarray(capacity.extent[2:], float) + capacity.reach
    nx = max(1, int(np.ceil((hi[0] - lo[0]) / capacity.cell_size)))
    ny = max(1, int(np.ceil((hi[1] - lo[1]) / capacity.cell_size)))
    return lo, (nx, ny)


def cell_walls(walls: Array, valid: Array, capacity: Capacity) -> tuple[Array, Array]:
    """``(cell_walls [C, K], overflow)``: each cell's walls closer than the reach to some point
    of the cell (its centre's distance within ``reach + cell / sqrt 2``), in wall order, the
    empty entries pointing at the last (padding) wall; ``overflow`` is True where some cell has
    more than ``K = capacity.cell_walls`` of them (a world the family's capacity cannot hold).
    A capacity whose cells hold every wall slot has one cell listing them all (nothing to
    compute: the planner masks the unused slots)."""
    count = walls.shape[0]
    if capacity.cell_walls >= count - 1:
        return jnp.arange(count - 1, dtype=jnp.int32)[None], jnp.asarray(False)
    origin, (nx, ny) = grid_layout(capacity)
    size = capacity.cell_size
    iy, ix = np.mgrid[0:ny, 0:nx]
    cx = jnp.asarray(origin[0] + (ix.ravel() + 0.5) * size, jnp.float32)[:, None]
    cy = jnp.asarray(origin[1] + (iy.ravel() + 0.5) * size, jnp.float32)[:, None]
    dist = point_segment_distance(cx, cy, walls[:, 0], walls[:, 1], walls[:, 2], walls[:, 3])
    near = (dist <= capacity.reach + size * np.sqrt(0.5)) & valid[None, :]  # [C, W]
    # each near wall's place in its cell's list (in wall order), by a running count: a
    # scatter, where a sort per cell would cost more
    place = jnp.where(near, jnp.cumsum(near, axis=1) - 1, capacity.cell_walls)
    rows = jnp.broadcast_to(jnp.arange(near.shape[0])[:, None], near.shape)
    lists = jnp.full((near.shape[0], capacity.cell_walls), count - 1, jnp.int32)
    lists = lists.at[rows, place].set(jnp.broadcast_to(jnp.arange(count, dtype=jnp.int32),
                                                       near.shape), mode="drop")
    return lists, jnp.any(jnp.sum(near, axis=1) > capacity.cell_walls)
