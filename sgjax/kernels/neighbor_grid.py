"""Cell lists for bodies: who is near whom, at a cost that grows with the crowd, not its square.

Bodies (pedestrians and robots, ``[M]`` positions in m) are sorted into the square cells of a
grid of ``cell`` m sides; each query point then reads the bodies of the cells within ``span``
cells of its own (the eight around it for a span of 1), at most ``capacity`` (static) per
cell. With ``span`` cells at least the interaction range, every body within the range of a
query is among its candidates, unless a cell held more than ``capacity`` present bodies: those
are counted in :attr:`BodyCells.overflow` (the environment reports the count in
``info["neighbor_overflow"]``), never silently dropped.

Static shapes throughout (``[Q, (2 span + 1)^2 capacity]`` candidates per query), so it
compiles once, runs under ``vmap`` and differentiates through the positions it gathers (the
cell choice itself is piecewise constant). Points outside the grid are clipped into its border
cells; clipping moves two points no farther apart, so a pair within one cell width stays in
neighbouring cells.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
from flax import struct
from jax import Array


@struct.dataclass
class BodyGrid:
    """Where the grid lies: ``origin [2]`` (m, its lower-left corner; may be traced), ``cell``
    (m, static) and ``shape`` ``(nx, ny)`` cells (static)."""

    origin: Array
    cell: float = struct.field(pytree_node=False, default=1.0)
    shape: tuple[int, int] = struct.field(pytree_node=False, default=(1, 1))

    @property
    def num_cells(self) -> int:
        """``nx * ny``."""
        return self.shape[0] * self.shape[1]

    def cell_xy(self, x: Array, y: Array) -> tuple[Array, Array]:
        """Integer cell coordinates ``(ix, iy)`` (int32, same shape as ``x``) of points (m),
        clipped to the grid."""
        nx, ny = self.shape
        ix = jnp.clip(jnp.floor((x - self.origin[0]) / self.cell), 0, nx - 1)
        iy = jnp.clip(jnp.floor((y - self.origin[1]) / self.cell), 0, ny - 1)
        return ix.astype(jnp.int32), iy.astype(jnp.int32)


def covering_grid(origin: Array, extent: tuple[float, float], cell: float) -> BodyGrid:
    """A grid of ``cell`` m squares from ``origin`` (m) covering ``extent`` ``(width,
    height)`` (m, static)."""
    if not cell > 0.0:
        raise ValueError(f"covering_grid: cell must be > 0 m, got {cell}")
    shape = (max(1, math.ceil(extent[0] / cell)), max(1, math.ceil(extent[1] / cell)))
    return BodyGrid(origin=jnp.asarray(origin, jnp.float32), cell=float(cell), shape=shape)


@struct.dataclass
class BodyCells:
    """Bodies sorted into cells. ``order [M]`` int32: body rows by cell (absent bodies last);
    ``start [C]`` int32: where each cell's bodies begin in ``order``; ``count [C]`` int32: how
    many present bodies each cell holds (possibly more than the capacity); ``overflow`` int32
    scalar: present bodies left out of some cell's list (0 when every list fits)."""

    order: Array
    start: Array
    count: Array
    overflow: Array


def sort_into_cells(grid: BodyGrid, x: Array, y: Array, present: Array, capacity: int
                    ) -> BodyCells:
    """Sort bodies at ``x, y`` ``[M]`` (m) with ``present [M]`` (bool) into ``grid``'s cells,
    ``capacity`` (static) listed per cell."""
    num_cells = grid.num_cells
    ix, iy = grid.cell_xy(x, y)
    cell = jnp.where(present, iy * grid.shape[0] + ix, num_cells)  # absent: one bucket past
    order = jnp.argsort(cell, stable=True).astype(jnp.int32)
    count = jnp.zeros(num_cells + 1, jnp.int32).at[cell].add(1)[:num_cells]
    start = (jnp.cumsum(count) - count).astype(jnp.int32)
    overflow = jnp.sum(jnp.maximum(count - capacity, 0))
    return BodyCells(order=order, start=start, count=count, overflow=overflow)


def candidates(grid: BodyGrid, cells: BodyCells, x: Array, y: Array, capacity: int,
               span: int = 1) -> tuple[Array, Array]:
    """The bodies in the cells within ``span`` (static) cells of query points ``x, y`` ``[Q]``
    (m), a square of ``S = (2 span + 1)^2`` cells: ``(index [Q, S K], listed [Q, S K])`` with
    ``K = capacity`` (static). Every body within ``span`` cell widths of a query is listed
    (unless its cell overflowed). ``index`` holds body rows, ``M`` (one past the last body:
    give the gathered arrays a padding row) where ``listed`` is False. A query that is itself
    a body finds itself among its candidates."""
    num_bodies = cells.order.shape[0]
    nx, ny = grid.shape
    ix, iy = grid.cell_xy(x, y)
    steps = jnp.arange(-span, span + 1, dtype=jnp.int32)
    cx = ix[:, None, None] + steps[None, :, None]  # [Q, 2 span + 1, 1]
    cy = iy[:, None, None] + steps[None, None, :]  # [Q, 1, 2 span + 1]
    inside = (cx >= 0) & (cx < nx) & (cy >= 0) & (cy < ny)
    cell = (jnp.clip(cy, 0, ny - 1) * nx + jnp.clip(cx, 0, nx - 1)).reshape(x.shape[0], -1)
    inside = inside.reshape(x.shape[0], -1)  # [Q, S]
    held = jnp.where(inside, jnp.minimum(cells.count[cell], capacity), 0)
    slot = jnp.arange(capacity, dtype=jnp.int32)
    listed = slot[None, None, :] < held[..., None]  # [Q, S, K]
    at = jnp.minimum(cells.start[cell][..., None] + slot, num_bodies - 1)
    index = jnp.where(listed, cells.order[at], num_bodies)
    return index.reshape(x.shape[0], -1), listed.reshape(x.shape[0], -1)


def pad_row(values: Array, fill: float | int | bool) -> Array:
    """``values [M]`` with one more row ``fill`` (the row :func:`candidates` points unlisted
    places at)."""
    return jnp.concatenate([values, jnp.full((1,), fill, values.dtype)])
