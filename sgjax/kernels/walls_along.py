"""The walls a ray or a segment can meet, read from the map's wall grid instead of every wall
(issue 67: lidar and line of sight on building floors).

The grid's cell lists hold every wall within the map's ``reach`` of any point of the cell
(:func:`sgjax.maps.arrays.compile_map`). A wall that crosses a ray at distance ``t`` from its
origin lies within ``reach`` of the ray point at the nearest of the samples ``reach (2j + 1)``,
``j = 0, 1, ...`` (they are ``2 reach`` apart), so the union of those samples' cell lists up to
the ray's length holds every wall it can meet: the same nearest hit as testing every wall.
A sample outside the grid reads the cell it is clipped to, which is no farther from any wall
(the grid covers the walls, and clipping onto it is a projection). Samples per ray:
``ceil(length / (2 reach))``; a 5 m lidar beam on SocialGym 2.0's floors (reach 2 m) reads 2
cell lists of 134 walls instead of GDC3's 5,647."""

from __future__ import annotations

import math

import jax.numpy as jnp
from jax import Array

from sgjax.kernels.contacts import Walls, uses_broad_phase


def uses_lists_along(m: Walls, length: float | None) -> bool:
    """Whether rays of at most ``length`` m (None: unbounded) read ``m``'s cell lists (static):
    a bounded length, on a map whose contacts take the broad phase, and fewer list entries per
    ray than walls."""
    if length is None or not uses_broad_phase(m):
        return False
    return samples_along(m, length) * m.cell_walls.shape[-1] < m.wall_x1.shape[-1]


def samples_along(m: Walls, length: float) -> int:
    """Cell lists a ray of ``length`` m reads (static)."""
    return max(1, math.ceil(length / (2.0 * float(m.reach))))


def walls_along(m: Walls, px: Array, py: Array, ux: Array, uy: Array, length: float
                ) -> Array:
    """``[..., S * Kw]`` int32: the rows of the walls that rays from ``(px, py)`` along the unit
    vectors ``(ux, uy)`` (broadcast shapes ``...``) can meet within ``length`` m (the module
    doc; padding rows point at the masked last wall, and a wall may appear more than once)."""
    count = samples_along(m, length)
    t = float(m.reach) * (2.0 * jnp.arange(count) + 1.0)  # [S] m along the ray
    qx, qy = px[..., None] + ux[..., None] * t, py[..., None] + uy[..., None] * t
    lists = m.cell_walls[m.cell_of(qx, qy)]  # [..., S, Kw]
    return lists.reshape(lists.shape[:-2] + (-1,))
