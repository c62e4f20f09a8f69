"""Compile a lowered JAX function and measure it: the one helper the bench scripts share."""

from __future__ import annotations

import time
from typing import Any


def compile_measured(lowered: Any) -> tuple[Any, float, int]:
    """``lowered.compile()`` timed. Returns the compiled function, its compile time (s) and its
    peak memory (bytes: arguments + outputs + temporaries, from XLA's memory analysis; 0 when
    the backend gives none)."""
    t0 = time.perf_counter()
    compiled = lowered.compile()
    seconds = time.perf_counter() - t0
    mem = compiled.memory_analysis()
    peak = 0 if mem is None else (mem.argument_size_in_bytes + mem.output_size_in_bytes
                                  + mem.temp_size_in_bytes)
    return compiled, seconds, int(peak)
