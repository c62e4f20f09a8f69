"""Spawn points of generated worlds: a jittered lattice inside a rectangle, every point a
margin away from the rectangle's sides."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array

JITTER = 0.3  # of a lattice cell: how far a point may move from its cell's centre


def lattice(key: Array, box: Array, columns: int, rows: int, margin: float) -> Array:
    """``[columns x rows, 2]`` points in ``box = (xmin, ymin, xmax, ymax)`` shrunk by ``margin``
    on every side: one per cell of a ``columns x rows`` grid, at the cell's centre moved by up
    to :data:`JITTER` of the cell each way."""
    x0, y0 = box[0] + margin, box[1] + margin
    width = jnp.maximum(box[2] - box[0] - 2 * margin, 0.0)
    height = jnp.maximum(box[3] - box[1] - 2 * margin, 0.0)
    iy, ix = jnp.meshgrid(jnp.arange(rows), jnp.arange(columns), indexing="ij")
    jitter = jax.random.uniform(key, (rows * columns, 2), jnp.float32, -JITTER, JITTER)
    fx = (ix.ravel() + 0.5 + jitter[:, 0]) / columns
    fy = (iy.ravel() + 0.5 + jitter[:, 1]) / rows
    return jnp.stack([x0 + fx * width, y0 + fy * height], axis=-1)
