"""The thresholds the metrics use: :class:`MetricConstants` (recorded in every evaluation
output; docs/metrics.md's constants table is generated from its fields)."""

from __future__ import annotations

import dataclasses
from typing import Any


def _constant(default: Any, unit: str, used_by: str) -> Any:
    return dataclasses.field(default=default, metadata={"unit": unit, "used_by": used_by})


@dataclasses.dataclass(frozen=True)
class MetricConstants:
    """The thresholds the metrics use (recorded in every evaluation output). Each field's
    ``metadata`` holds its ``unit`` and what uses it (the table in docs/metrics.md)."""

    stop_speed: float = _constant(
        0.01, "m/s", "stop time, freezes, deadlock: \"stopped\" below this speed "
        "(HuNavSim's threshold)")
    stop_turn_rate: float = _constant(0.02, "rad/s", "same, and below this turn rate (HuNavSim)")
    freeze_time: float = _constant(
        1.0, "s", "a freezing event is a stop at least this long while on the way")
    deadlock_time: float = _constant(
        5.0, "s", "deadlock: two or more unfinished robots all stopped this long")
    space_radii: tuple[float, float, float] = _constant(
        (0.45, 1.2, 3.6), "m", "intimate, personal, social space (Hall; HuNavSim, SEAN)")
    ttc_threshold: float = _constant(
        2.0, "s", "ttc_below_threshold: fraction of steps with time-to-collision below it")
    ttc_cap: float = _constant(
        10.0, "s", "time-to-collision is capped here (no approach at all reads the cap)")

    def as_dict(self) -> dict[str, float | list[float]]:
        return {k: list(v) if isinstance(v, tuple) else v
                for k, v in dataclasses.asdict(self).items()}


DEFAULT_CONSTANTS = MetricConstants()
SPACE_NAMES = ("intimate", "personal", "social")
