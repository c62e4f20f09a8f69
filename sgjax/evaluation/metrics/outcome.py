"""Outcome metrics: who arrived, who timed out or was ended, how long the episode ran."""

from __future__ import annotations

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.evaluation.metrics.base import Metric, episode_metric, robot_metric, team_success
from sgjax.evaluation.metrics.constants import MetricConstants
from sgjax.evaluation.metrics.registration import register_metric
from sgjax.evaluation.metrics.step_view import EpisodeEnd, StepView, collision_onsets


@struct.dataclass
class OutcomeTally:
    """``[R]``: a collision onset in a step the robot started unfinished (so before it
    arrived, the arrival step included)."""

    collided_before_arrival: Array  # bool


@register_metric
class Outcome(Metric):
    """Success, team success, clean success, timeouts, collision ends, episode length and
    stuck ends: read from the final state, and for clean success whether a collision began
    before the robot arrived (the episode length is the runner's common tally)."""

    infos = (
        robot_metric("success", "fraction",
                     "robot reached its goal (centre within goal_tolerance) before the episode "
                     "ended; the episode value is the fraction of its robots (partial success)",
                     "SocialGym 2.0 `succeeded`; socialnav.md C1"),
        episode_metric("team_success", "fraction", "every robot of the episode reached its goal",
                       "SocialGym 2.0 success_rate", binary=True),
        robot_metric("clean_success", "fraction",
                     "reached the goal with no collision onset of any kind before it arrived "
                     "(in the steps it started unfinished, the arrival step included; contacts "
                     "while settling or parked afterwards do not count)",
                     "socialnav.md C1 (Success)"),
        robot_metric("timeout", "fraction",
                     "robot neither arrived nor was ended by an ender when the episode ended "
                     "(time limit or stuck truncation)", "socialnav.md C1"),
        robot_metric("collision_ended", "fraction",
                     "robot was ended by the collision ender (0 unless that ender is "
                     "configured)", "sgjax"),
        episode_metric("episode_length", "steps",
                       "steps until every robot finished or the episode was truncated: the "
                       "paper's Avg. Length", "SocialGym 2.0 avg_length"),
        episode_metric("stuck_end", "fraction",
                       "the episode was truncated before the time limit (stuck ender)",
                       "SocialGym 2.0", binary=True),
    )

    def start(self, num_robots: int, num_zones: int, constants: MetricConstants) -> OutcomeTally:
        return OutcomeTally(collided_before_arrival=jnp.zeros(num_robots, bool))

    def update(self, tally: OutcomeTally, view: StepView) -> OutcomeTally:
        began = collision_onsets(view.state) > collision_onsets(view.prev)
        return OutcomeTally(
            collided_before_arrival=tally.collided_before_arrival | (view.was_active & began))

    def finalize(self, tally: OutcomeTally, end: EpisodeEnd) -> dict[str, Array]:
        robots, present = end.robots, end.present
        return {
            "success": end.success,
            "team_success": team_success(present, robots.succeeded),
            "clean_success": end.success & ~tally.collided_before_arrival,
            "timeout": present & ~robots.finished,
            "collision_ended": present & robots.ended,
            "episode_length": end.length,
            "stuck_end": ((end.length < end.params.max_steps)
                          & ~jnp.all(~present | robots.finished)),
        }
