"""The one training loop: lanes of a trainer advanced in calls of a number of updates, each
call one compiled program (``Trainer.jitted_chunk_lanes``), with the caller's work between
calls (progress, evaluation, checkpoints, refilled lanes).

``python -m train``, ``train.reproduce``, ``train.ablation`` and ``train.sweep`` all train
through :func:`train_in_calls`; what each does between calls is its ``after_call``.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from typing import Any

import jax

from train.algorithm.learner import divisor_up_to
from train.run.phases import Phases


@dataclasses.dataclass
class Call:
    """One training call, as ``after_call`` sees it: the lanes after it (``runner``, which
    ``after_call`` may replace: refilled lanes), the call's metrics ``{name: [lanes,
    count]}``, the updates done after it and in it, and its wall-clock seconds. ``after_call``
    sets ``stop`` to end the loop early (an open-ended run: ``total`` None)."""

    runner: Any
    logs: dict
    done: int
    count: int
    seconds: float
    stop: bool = False


def equal_calls(total: int, times: int) -> int:
    """Updates per call for a run of ``total`` updates in about ``times`` equal calls (one
    compiled program for the whole run): the largest divisor of ``total`` up to ``ceil(total
    / times)`` (more calls where ``total`` has no divisor near that)."""
    return divisor_up_to(total, max(1, -(-total // times)))


def train_in_calls(trainer: Any, runner: Any, per_call: int, total: int | None, *,
                   done: int = 0, donate: bool = False, phases: Phases | None = None,
                   after_call: Callable[[Call], None] | None = None) -> tuple[Any, int]:
    """Advance the lanes ``runner`` (leaves ``[L, ...]``) of ``trainer`` from ``done`` to
    ``total`` updates in calls of ``per_call`` updates (the last call shorter where
    ``per_call`` does not divide what is left; ``total`` None: until ``after_call`` stops),
    calling ``after_call`` after each. A call's program is compiled ahead of its first call,
    once per trainer and shapes (``Trainer.compiled_chunk_lanes``), and timed as phase
    ``compile``; each call is timed as ``train`` (``phases``). Returns the
    lanes and the updates done. ``donate``: the runner's buffers are reused by the call (the
    caller keeps no reference to the runner it passes)."""
    phases = phases if phases is not None else Phases()
    program = None
    while total is None or done < total:
        count = per_call if total is None else min(per_call, total - done)
        if program is None or count != per_call:
            program, seconds = trainer.compiled_chunk_lanes(count, runner, donate)
            phases.add("compile", seconds)
        t0 = time.perf_counter()
        runner, logs = program(runner)
        jax.block_until_ready(logs)
        seconds = time.perf_counter() - t0
        phases.add("train", seconds)
        done += count
        call = Call(runner, logs, done, count, seconds)
        if after_call is not None:
            after_call(call)
        runner = call.runner
        if call.stop:
            break
    return runner, done
