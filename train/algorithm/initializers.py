"""Weight initialisers that are safe to ``vmap`` over seeds and lanes on XLA:CPU.

``orthogonal`` draws the same matrices as ``jax.nn.initializers.orthogonal`` (QR of a standard
normal matrix, columns signed by ``diag(R)``, times ``scale``), but its QR never runs batched:
under ``vmap`` it loops over the lanes (``jax.custom_batching.sequential_vmap``).

Why: jaxlib's CPU LAPACK kernels split a *batched* factorisation over XLA's intra-op thread pool
and block the calling pool thread until the pieces finish, while XLA:CPU runs independent
operations of one program concurrently on that same pool. A network initialised under
``vmap(init)`` over seeds holds several independent batched QRs (one per layer); when more of
them run at once than the pool has threads, every thread waits for work queued behind it and
the program never finishes (0% CPU, every thread on a futex). On a 2-core machine three
concurrent batched QRs hang within the first trials. ``docs/xla-cpu-deadlock.md`` has the
reproduction and the measurements.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp
from jax import Array


@jax.custom_batching.sequential_vmap
def _orthonormal_columns(matrix: Array) -> Array:
    """``Q`` of ``matrix [n, m]`` (``n >= m``) with columns signed so that ``diag(R) > 0``."""
    q, r = jnp.linalg.qr(matrix)
    return q * jnp.sign(jnp.diagonal(r))[None, :]


def orthogonal(scale: float = 1.0) -> Callable[[Array, Sequence[int], jnp.dtype], Array]:
    """Initialiser ``(key, shape, dtype) -> [*shape]``: a (semi-)orthogonal matrix times
    ``scale``, the last axis being the columns (Flax's ``Dense`` kernel ``[in, out]``)."""

    def init(key: Array, shape: Sequence[int], dtype: jnp.dtype = jnp.float32) -> Array:
        columns = shape[-1]
        rows = math.prod(shape) // columns
        tall = rows >= columns
        draw = jax.random.normal(key, (rows, columns) if tall else (columns, rows), dtype)
        q = _orthonormal_columns(draw)
        q = q if tall else q.T
        return (scale * q).reshape(shape).astype(dtype)

    return init
