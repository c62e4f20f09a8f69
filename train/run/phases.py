"""Where a command's time goes: named phases of wall-clock seconds."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator


class Phases:
    """Seconds by phase name, in the order the phases were named. ``with
    phases.timing("train"):`` adds the block's wall-clock seconds to ``train``."""

    def __init__(self, *names: str):
        self.seconds: dict[str, float] = dict.fromkeys(names, 0.0)
        self.started = time.perf_counter()

    @contextlib.contextmanager
    def timing(self, name: str) -> Iterator[None]:
        """Time the block into phase ``name``."""
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.add(name, time.perf_counter() - t0)

    def add(self, name: str, seconds: float) -> None:
        """Add ``seconds`` to phase ``name`` (created at 0)."""
        self.seconds[name] = self.seconds.get(name, 0.0) + float(seconds)

    def elapsed(self) -> float:
        """Seconds since these phases were created."""
        return time.perf_counter() - self.started

    def line(self, note: str = "") -> str:
        """``time: train 50 s, evaluate 3 s; total 60 s`` (``note`` after the phases)."""
        parts = ", ".join(f"{name} {value:.0f} s" for name, value in self.seconds.items())
        return f"time: {parts}{note}; total {self.elapsed():.0f} s"
