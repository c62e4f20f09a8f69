"""Stop metrics: time stopped on the way, freezing events, and deadlock of the team."""

from __future__ import annotations

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.evaluation.metrics.base import Metric, episode_metric, robot_metric
from sgjax.evaluation.metrics.constants import MetricConstants
from sgjax.evaluation.metrics.registration import register_metric
from sgjax.evaluation.metrics.step_view import EpisodeEnd, StepView


@struct.dataclass
class StopTally:
    """``[R]`` int32 unless noted."""

    stop_steps: Array  # steps stopped on the way
    stopped_run: Array  # consecutive stopped steps so far
    freezes: Array  # stops that reached freeze_time
    stall_run: Array  # int32 scalar: consecutive steps with every unfinished robot stopped
    deadlock: Array  # bool scalar: a stall reached deadlock_time


def steps_of(seconds: float, dt: Array) -> Array:
    """The number of steps (at least 1) that last ``seconds`` at step ``dt`` (s)."""
    return jnp.maximum(jnp.ceil(seconds / dt - 1e-6), 1)


@register_metric
class Stops(Metric):
    """Stopped: unfinished, slower than ``stop_speed`` and turning slower than
    ``stop_turn_rate`` (:attr:`StepView.stopped`)."""

    infos = (
        robot_metric("stop_time", "s",
                     "dt x steps on the way (not finished) with speed < stop_speed and |turn "
                     "rate| < stop_turn_rate",
                     "HuNavSim time_not_moving; the paper's Stop Time"),
        robot_metric("freezes", "count",
                     "stops lasting freeze_time or longer while on the way, summed over robots",
                     "socialnav.md C1 (freezing)", reduce="sum"),
        episode_metric("deadlock", "fraction",
                       "two or more unfinished robots, all stopped, for deadlock_time or longer",
                       "socialnav.md C1 (multi-robot)", binary=True),
    )

    def start(self, num_robots: int, num_zones: int, constants: MetricConstants) -> StopTally:
        zi = jnp.zeros(num_robots, jnp.int32)
        return StopTally(stop_steps=zi, stopped_run=zi, freezes=zi,
                         stall_run=jnp.zeros((), jnp.int32), deadlock=jnp.zeros((), bool))

    def update(self, tally: StopTally, view: StepView) -> StopTally:
        c, running = view.constants, view.running
        stopped, still_active = view.stopped, view.still_active
        stopped_run = jnp.where(stopped, tally.stopped_run + 1, 0)
        freeze_steps = steps_of(c.freeze_time, view.dt).astype(jnp.int32)
        # Deadlock: two or more unfinished robots, all stopped.
        stalled = (jnp.sum(still_active) >= 2) & jnp.all(stopped | ~still_active)
        stall_run = jnp.where(stalled, tally.stall_run + 1, 0)
        return StopTally(
            stop_steps=view.add(tally.stop_steps, 1, stopped),
            stopped_run=stopped_run,
            freezes=view.add(tally.freezes, 1, stopped & (stopped_run == freeze_steps)),
            stall_run=jnp.where(running, stall_run, tally.stall_run),
            deadlock=tally.deadlock | (running & (stall_run >= steps_of(c.deadlock_time,
                                                                        view.dt))),
        )

    def finalize(self, tally: StopTally, end: EpisodeEnd) -> dict[str, Array]:
        return {"stop_time": tally.stop_steps * end.dt, "freezes": tally.freezes,
                "deadlock": tally.deadlock}
