"""Which bodies each pedestrian interacts with: every body, or those within a range found
through cell lists (:mod:`sgjax.kernels.neighbor_grid`).

The force models read the others as arrays broadcast against the pedestrians: :class:`Pairs`
holds ``P`` places per pedestrian, either every body (``P = M``, the arrays gathered as one
shared row ``[1, M]``, all ``H`` pedestrians at once) or each pedestrian's candidates from the
cells around it (``P = (2 SPAN + 1)^2 capacity``, ``[B, P]`` for a block of ``B``
pedestrians: :func:`map_pairs`). ``weight`` masks the pedestrian itself, absent bodies,
unlisted places and (with a range) bodies farther than the range, so a sum over places is the
sum over the interacting bodies in either layout: with no cell over its capacity the two
layouts give the same forces up to the order of the floating-point sum.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import jax
import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.kernels.neighbor_grid import (
    BodyCells,
    BodyGrid,
    candidates,
    covering_grid,
    pad_row,
    sort_into_cells,
)

FAR = 1.0e6  # m: where the padding body stands (no force law reaches it)
# Cells per neighbour range: a pedestrian reads the (2 SPAN + 1)^2 cells around its own; finer
# cells read a square closer to the range's disc (bench/crowd_scale.py measured the choice).
SPAN = 2
SEARCHES = ("auto", "all", "grid")
# Pedestrians from which the cell lists pay when a range is set (sgjax.make's "auto"):
# bench/crowd_scale.py, 2-core CPU, 40 m crossing: with 500 pedestrians every body is 1.8x
# faster than the lists (a pedestrian reads about 350 listed places, and every body is only
# 504); with 1,000 the lists are 1.28x faster.
GRID_FROM_HUMANS = 1000
# Bodies per m^2 a cell list holds by default: 6, near the crush density of crowd research
# (people stand at 6 to 7 per m^2 only when pressed together; Fruin's level of service F
# begins at about 2 per m^2). The 40 m crossing of bench/crowd_scale.py peaks at 4.4 per m^2
# in a 1.5 m cell with 1,000 pedestrians (at their packed spawn slots). A fuller cell is
# counted in info["neighbor_overflow"]; raise human_cell_capacity for denser crowds.
DENSITY_CAPACITY = 6.0


@struct.dataclass
class Pairs:
    """The others of a block of pedestrians. ``index [B, P]`` int32 body rows (``None``: every
    body, in row order); ``weight [B, P]`` float factors (0: no interaction)."""

    weight: Array
    index: Array | None = None

    def gather(self, values: Array, fill: float = FAR) -> Array:
        """``values [M]`` (one per body) at each pedestrian's places: ``[1, M]`` for every
        body, ``[H, P]`` from the cells (``fill`` at unlisted places)."""
        if self.index is None:
            return values[None, :]
        return pad_row(values, fill)[self.index]


def cell_capacity(cell: float, density: float = DENSITY_CAPACITY) -> int:
    """Bodies listed per cell of ``cell`` m sides by default: ``density`` per m^2, at least
    8."""
    return max(8, math.ceil(density * cell * cell))


def body_grid(m, cell: float) -> BodyGrid:
    """A grid of ``cell`` m squares over the map's wall grid (``m``: ``MapArrays``; bodies
    beyond it fall into its border cells)."""
    nx, ny = m.grid_shape
    return covering_grid(m.grid_origin, (nx * m.cell_size, ny * m.cell_size), cell)


# Pedestrians per block of the cell-list path: their candidates' arrays ([block, P] each) stay
# in cache (bench/crowd_scale.py, 2-core CPU: 1,000 pedestrians 2.5x faster than all at once).
BLOCK = 128

# ``each(fn, bx, by, body_weight, *per_pedestrian) -> (outputs, overflow)``: the pairs of the
# bodies ``[M]`` with the pedestrians, handed to ``fn(pairs, *per_pedestrian_block)``
Each = Callable[..., tuple[tuple[Array, ...], Array]]


def dense_pairs(x: Array, y: Array, bx: Array, by: Array, body_weight: Array,
                neighbor_range: float | None) -> Pairs:
    """Every body's pair with each pedestrian at ``x, y`` ``[H]`` (m; the first ``H`` bodies
    are the pedestrians, in order): the body's weight, 0 for the pedestrian itself and (with
    a ``neighbor_range``, m) for bodies at least that far."""
    num_humans, num_bodies = x.shape[0], bx.shape[0]
    not_self = ~jnp.eye(num_humans, num_bodies, dtype=bool)
    weight = not_self.astype(jnp.float32) * body_weight[None, :]
    if neighbor_range is not None:
        gap_sq = jnp.square(bx[None, :] - x[:, None]) + jnp.square(by[None, :] - y[:, None])
        weight = weight * (gap_sq < neighbor_range * neighbor_range).astype(jnp.float32)
    return Pairs(weight=weight)


def listed_pairs(grid: BodyGrid, cells: BodyCells, rows: Array, x: Array, y: Array,
                 bx: Array, by: Array, body_weight: Array, neighbor_range: float,
                 capacity: int) -> Pairs:
    """The pairs of pedestrians ``rows [B]`` (their body rows) at ``x, y`` ``[B]`` (m) with
    the bodies listed in the cells around them (``cells``: the bodies ``bx, by`` ``[M]``
    sorted into ``grid``), nearer than ``neighbor_range`` (m)."""
    index, listed = candidates(grid, cells, x, y, capacity, SPAN)
    gap_sq = (jnp.square(pad_row(bx, FAR)[index] - x[:, None])
              + jnp.square(pad_row(by, FAR)[index] - y[:, None]))
    near = listed & (index != rows[:, None]) & (gap_sq < neighbor_range * neighbor_range)
    weight = near.astype(jnp.float32) * pad_row(body_weight, 0.0)[index]
    return Pairs(weight=weight, index=index)


def map_pairs(
    fn: Callable[..., tuple[Array, ...]], x: Array, y: Array, bx: Array, by: Array,
    body_weight: Array, per_pedestrian: tuple[Array, ...], neighbor_range: float | None,
    grid: BodyGrid | None, capacity: int, block: int = BLOCK,
) -> tuple[tuple[Array, ...], Array]:
    """``fn(pairs, x, y, *per_pedestrian) -> outputs`` (each ``[H]``, or ``[H, ...]``) for
    pedestrians at ``x, y`` ``[H]`` (m) among bodies ``bx, by`` ``[M]`` (m; the first ``H``
    rows are the pedestrians themselves, in order) of weight ``body_weight [M]`` (0: absent
    or unseen), and the bodies a full cell list left out (int32). ``neighbor_range`` (m,
    static): bodies at least this far do not interact (``None``: no range). Without a
    ``grid``, ``fn`` sees every body at once (:func:`dense_pairs`); with one (its
    :data:`SPAN` cells at least the range), ``block`` pedestrians at a time (a
    ``lax.map``), each with the bodies listed in the cells around it (``capacity`` per
    cell)."""
    if grid is None:
        return tuple(fn(dense_pairs(x, y, bx, by, body_weight, neighbor_range), x, y,
                        *per_pedestrian)), jnp.zeros((), jnp.int32)
    if neighbor_range is None or grid.cell * SPAN < neighbor_range * (1.0 - 1e-6):
        raise ValueError(f"map_pairs: {SPAN} cells of the grid ({grid.cell} m each) must "
                         f"span at least the neighbour range ({neighbor_range} m)")
    cells = sort_into_cells(grid, bx, by, body_weight != 0.0, capacity)
    num = x.shape[0]
    blocks = -(-num // block)

    def blocked(a: Array) -> Array:  # [H, ...] -> [blocks, block, ...], padded with row 0
        padded = jnp.concatenate([a, jnp.repeat(a[:1], blocks * block - num, axis=0)])
        return padded.reshape(blocks, block, *a.shape[1:])

    # the padding copies of pedestrian 0 are pedestrian 0 (never paired with itself: a pair at
    # distance 0 would turn gradients NaN even though their outputs are dropped)
    rows = blocked(jnp.arange(num, dtype=jnp.int32))

    def one(args: tuple[Array, ...]) -> tuple[Array, ...]:
        r, xb, yb, *rest = args
        pairs = listed_pairs(grid, cells, r, xb, yb, bx, by, body_weight, neighbor_range,
                             capacity)
        return tuple(fn(pairs, xb, yb, *rest))

    out = jax.lax.map(one, (rows, blocked(x), blocked(y),
                            *(blocked(a) for a in per_pedestrian)))
    return tuple(o.reshape(blocks * block, *o.shape[2:])[:num] for o in out), cells.overflow


def every_body(num_humans: int) -> Each:
    """:data:`Each` over every body, no range (the laws as published), for the
    ``num_humans`` pedestrians heading the bodies."""
    def each(fn: Callable[..., tuple[Array, ...]], bx: Array, by: Array, body_weight: Array,
             *per_pedestrian: Array) -> tuple[tuple[Array, ...], Array]:
        return map_pairs(fn, bx[:num_humans], by[:num_humans], bx, by, body_weight,
                         per_pedestrian, None, None, 0)

    return each


def uses_grid(neighbor_range: float | None, search: str, max_humans: int) -> bool:
    """Whether pedestrians find their pairs through cell lists: with a ``neighbor_range`` and
    ``search`` ``"grid"``, or ``"auto"`` from :data:`GRID_FROM_HUMANS` pedestrians (static)."""
    if search not in SEARCHES:
        raise ValueError(f"neighbor search must be one of {SEARCHES}, got {search!r}")
    if search == "grid" and neighbor_range is None:
        raise ValueError("neighbor search 'grid' needs a neighbour range (m)")
    return neighbor_range is not None and (
        search == "grid" or (search == "auto" and max_humans >= GRID_FROM_HUMANS))
