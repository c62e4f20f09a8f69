"""Proximity metrics: closest approach to other robots and pedestrians, and the fraction of
steps with someone inside each of Hall's spaces (intimate, personal, social)."""

from __future__ import annotations

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.evaluation.metrics.base import Metric, known, robot_metric
from sgjax.evaluation.metrics.constants import DEFAULT_CONSTANTS, SPACE_NAMES, MetricConstants
from sgjax.evaluation.metrics.registration import register_metric
from sgjax.evaluation.metrics.step_view import EpisodeEnd, StepView


@struct.dataclass
class ProximityTally:
    """``[R]`` unless noted."""

    min_gap_robot: Array  # m (inf: never another robot)
    min_gap_human: Array  # m (inf: never a pedestrian)
    near_robot: Array  # [3, R] int32: steps with the nearest robot inside each space radius
    near_human: Array  # [3, R] int32: the same for pedestrians


def _space_metrics() -> tuple:
    return tuple(
        robot_metric(f"{space}_space_{kind}", "fraction",
                     f"fraction of active steps with the nearest {kind} body gap < {radius} m "
                     f"(space_radii[{k}]; NaN without any {kind} body)", "HuNavSim, SEAN")
        for kind in ("human", "robot")
        for k, (space, radius) in enumerate(
            zip(SPACE_NAMES, DEFAULT_CONSTANTS.space_radii, strict=True)))


@register_metric
class Proximity(Metric):
    """Body gaps (centre distance - both radii) after each active step, from
    :attr:`StepView.nearest_robot` and :attr:`StepView.nearest_human`."""

    infos = (
        robot_metric("min_distance_human", "m",
                     "min over active steps and pedestrians of centre distance - both radii "
                     "(NaN without pedestrians)", "HuNavSim, socialnav.md C1"),
        robot_metric("min_distance_robot", "m",
                     "min over active steps and other robots in the world (active, settling or "
                     "parked) of centre distance - both radii", "socialnav.md C1"),
        *_space_metrics(),
    )

    def start(self, num_robots: int, num_zones: int, constants: MetricConstants
              ) -> ProximityTally:
        inf = jnp.full(num_robots, jnp.inf, jnp.float32)
        near = jnp.zeros((len(constants.space_radii), num_robots), jnp.int32)
        return ProximityTally(min_gap_robot=inf, min_gap_human=inf, near_robot=near,
                              near_human=near)

    def update(self, tally: ProximityTally, view: StepView) -> ProximityTally:
        radii = jnp.asarray(view.constants.space_radii, jnp.float32)[:, None]
        robot, human, active = view.nearest_robot, view.nearest_human, view.was_active
        return ProximityTally(
            min_gap_robot=view.least(tally.min_gap_robot, robot),
            min_gap_human=view.least(tally.min_gap_human, human),
            near_robot=tally.near_robot + (active & (robot < radii)).astype(jnp.int32),
            near_human=tally.near_human + (active & (human < radii)).astype(jnp.int32),
        )

    def finalize(self, tally: ProximityTally, end: EpisodeEnd) -> dict[str, Array]:
        saw_robot = jnp.isfinite(tally.min_gap_robot)
        saw_human = jnp.isfinite(tally.min_gap_human)
        out = {"min_distance_human": known(tally.min_gap_human, saw_human),
               "min_distance_robot": known(tally.min_gap_robot, saw_robot)}
        for k, space in enumerate(SPACE_NAMES):
            out[f"{space}_space_human"] = known(tally.near_human[k] / end.steps, saw_human)
            out[f"{space}_space_robot"] = known(tally.near_robot[k] / end.steps, saw_robot)
        return out
