"""A scan that stops early: steps in chunks inside a ``lax.while_loop`` that checks between
chunks whether the carry is done (the evaluator's episodes run until every one has ended)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import jax
import jax.numpy as jnp
from jax import Array

C = TypeVar("C")


def scan_until_done(step: Callable[[C, Any], C], carry: C, done: Callable[[C], Array],
                    max_steps: int, chunk: int, xs: Any = None,
                    record: Callable[[C], Any] | None = None, stop_early: bool = True
                    ) -> tuple[C, Any, Array]:
    """Apply ``step(carry, x)`` up to ``max_steps`` times, stopping once ``done(carry)``.

    ``xs``: per-step inputs with leading axis ``max_steps`` (default: the step index, int32).
    The steps run in chunks of ``chunk`` steps inside a ``lax.while_loop`` that checks
    ``done`` between chunks, so a run that is done early costs the chunks it took (a step
    after ``done`` must leave ``carry`` as it is for the results to equal the full scan); the
    last chunk is cut at ``max_steps``. ``stop_early=False`` is one plain ``lax.scan`` of
    every step.

    Returns ``(carry, ys, steps_run)``: ``ys`` (None without ``record``) holds
    ``record(carry)`` after every step ``[max_steps, ...]``, the final carry's for the steps
    not run; ``steps_run`` (int32) is the number of steps taken (whole chunks, at most
    ``max_steps``)."""
    if xs is None:
        xs = jnp.arange(max_steps, dtype=jnp.int32)

    def recorded(c: C) -> Any:
        return None if record is None else record(c)

    if not stop_early:
        carry, ys = jax.lax.scan(lambda c, x: (lambda n: (n, recorded(n)))(step(c, x)),
                                 carry, xs, length=max_steps)
        return carry, ys, jnp.asarray(max_steps, jnp.int32)
    chunk = max(1, min(chunk, max_steps))
    chunks = -(-max_steps // chunk)
    rows = (None if record is None else jax.tree.map(
        lambda s: jnp.zeros((max_steps,) + s.shape, s.dtype), jax.eval_shape(record, carry)))

    def one_step(t: Array, loop: tuple) -> tuple:
        c, rows = loop
        c = step(c, jax.tree.map(lambda v: jax.lax.dynamic_index_in_dim(v, t, keepdims=False),
                                 xs))
        if record is not None:
            rows = jax.tree.map(lambda r, y: jax.lax.dynamic_update_index_in_dim(r, y, t, 0),
                                rows, record(c))
        return c, rows

    def unfinished(loop: tuple) -> Array:
        i, c, _ = loop
        return (i < chunks) & ~done(c)

    def run_chunk(loop: tuple) -> tuple:
        i, c, rows = loop
        first = i * chunk
        c, rows = jax.lax.fori_loop(first, jnp.minimum(first + chunk, max_steps), one_step,
                                    (c, rows))
        return i + 1, c, rows

    i, carry, rows = jax.lax.while_loop(unfinished, run_chunk,
                                        (jnp.zeros((), jnp.int32), carry, rows))
    steps_run = jnp.minimum(i * chunk, max_steps)
    ys = None
    if record is not None:  # the rows never played hold the final carry's record
        played = jnp.arange(max_steps) < steps_run
        ys = jax.tree.map(lambda r, last: jnp.where(
            played.reshape((-1,) + (1,) * last.ndim), r, last[None]), rows, record(carry))
    return carry, ys, steps_run
