"""Time and path metrics: time to goal, path length, SPL and path irregularity."""

from __future__ import annotations

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.evaluation.metrics.base import Metric, known, robot_metric
from sgjax.evaluation.metrics.constants import MetricConstants
from sgjax.evaluation.metrics.registration import register_metric
from sgjax.evaluation.metrics.step_view import EpisodeEnd, StepView
from sgjax.kernels.geometry import wrap_angle


@struct.dataclass
class PathTally:
    """``[R]`` each."""

    arrived_at: Array  # int32: arrival step (0: not arrived)
    length: Array  # m: distance moved while active
    turning: Array  # rad: total |heading change| while active


@register_metric
class Paths(Metric):
    """How long and how straight each robot's way to its goal was."""

    infos = (
        robot_metric("time_to_goal", "s",
                     "arrival step x dt, successful robots only (NaN without one)",
                     "CrowdNav, socialnav.md C1"),
        robot_metric("path_length", "m", "sum of the distances moved per step while active",
                     "socialnav.md C1"),
        robot_metric("spl", "fraction",
                     "success x L / max(L, path_length), L the length of the shortest route on "
                     "the map's navigation graph from start to goal",
                     "Anderson et al. 2018; socialnav.md C1"),
        robot_metric("path_irregularity", "rad",
                     "total rotation: sum over active steps of |wrap(heading change)|",
                     "HuNavSim CHC, SEAN"),
        robot_metric("path_irregularity_per_m", "rad/m",
                     "path_irregularity / path_length (NaN below 1 mm)", "SocNavBench"),
    )

    def start(self, num_robots: int, num_zones: int, constants: MetricConstants) -> PathTally:
        zf = jnp.zeros(num_robots, jnp.float32)
        return PathTally(arrived_at=jnp.zeros(num_robots, jnp.int32), length=zf, turning=zf)

    def update(self, tally: PathTally, view: StepView) -> PathTally:
        turned = jnp.abs(wrap_angle(view.state.robots.heading - view.prev.robots.heading))
        return PathTally(arrived_at=jnp.where(view.arrived, view.state.time, tally.arrived_at),
                         length=view.add(tally.length, view.moved),
                         turning=view.add(tally.turning, turned))

    def finalize(self, tally: PathTally, end: EpisodeEnd) -> dict[str, Array]:
        shortest = end.state.route.total_length  # m
        length = tally.length
        return {
            "time_to_goal": known(tally.arrived_at * end.dt, end.success),
            "path_length": length,
            "spl": end.success * shortest / jnp.maximum(jnp.maximum(shortest, length), 1e-6),
            "path_irregularity": tally.turning,
            "path_irregularity_per_m": known(tally.turning / jnp.maximum(length, 1e-3),
                                             length >= 1e-3),
        }
