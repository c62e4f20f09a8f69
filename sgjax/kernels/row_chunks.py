"""Work on the flagged rows of a batch alone, a fixed-size chunk of them at a time.

A batch of ``N`` rows where few are flagged in a step (environments whose episode ended, whose
robot was truncated) need not pay for the others: :func:`update_flagged_rows` runs an update on
``chunk`` flagged rows at a time in a ``while_loop`` that runs ``ceil(flagged / chunk)`` times
(none when nothing is flagged). Static shapes throughout, so it compiles once and works under
``vmap`` (batched over lanes, the loop runs as often as the busiest lane needs). Used by
``SocialNavEnv.step_batch`` (new episodes for the ended environments) and the trainer's
bootstrap values (the critic on the truncating environments).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

import jax
import jax.numpy as jnp
from jax import Array

C = TypeVar("C")

MIN_CHUNK = 8  # rows: the smallest default chunk (chunk_size)


def chunk_size(rows: int, minimum: int = MIN_CHUNK) -> int:
    """The default chunk for a batch of ``rows``: a sixteenth of it, at least ``minimum``, at
    most ``rows``."""
    return min(rows, max(minimum, -(-rows // 16)))


def update_flagged_rows(flags: Array, chunk: int, update: Callable[[Array, C], C], init: C
                        ) -> C:
    """Fold ``update(index, carry) -> carry`` over the rows where ``flags [N]`` (bool) holds,
    ``chunk`` rows at a time, in row order. ``index [chunk]`` int32 holds the chunk's row
    numbers; the unused places of the last chunk hold ``N`` (past the end: gather with a clamp,
    scatter with ``mode="drop"``). Returns the final carry (``init`` when no row is flagged)."""
    num_rows = flags.shape[0]
    rank = jnp.cumsum(flags.astype(jnp.int32)) - 1  # [N]: order among the flagged
    count = jnp.sum(flags.astype(jnp.int32))

    def more(loop: tuple) -> Array:
        return loop[0] * chunk < count

    def body(loop: tuple) -> tuple:
        i, carry = loop
        (index,) = jnp.nonzero(flags & (rank // chunk == i), size=chunk, fill_value=num_rows)
        return i + 1, update(index, carry)

    return jax.lax.while_loop(more, body, (jnp.int32(0), init))[1]
