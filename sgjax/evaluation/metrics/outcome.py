"""Outcome metrics: who arrived, who timed out or was ended, how long the episode ran."""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array

from sgjax.evaluation.metrics.base import Metric, episode_metric, robot_metric, team_success
from sgjax.evaluation.metrics.registration import register_metric
from sgjax.evaluation.metrics.step_view import EpisodeEnd


@register_metric
class Outcome(Metric):
    """Success, team success, clean success, timeouts, collision ends, episode length and
    stuck ends: read from the final state (no accumulator; the episode length is the runner's
    common tally)."""

    infos = (
        robot_metric("success", "fraction",
                     "robot reached its goal (centre within goal_tolerance) before the episode "
                     "ended; the episode value is the fraction of its robots (partial success)",
                     "SocialGym 2.0 `succeeded`; socialnav.md C1"),
        episode_metric("team_success", "fraction", "every robot of the episode reached its goal",
                       "SocialGym 2.0 success_rate", binary=True),
        robot_metric("clean_success", "fraction",
                     "reached the goal with no collision onset of any kind",
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

    def finalize(self, tally: tuple, end: EpisodeEnd) -> dict[str, Array]:
        robots, present = end.robots, end.present
        return {
            "success": end.success,
            "team_success": team_success(present, robots.succeeded),
            "clean_success": end.success & (end.collisions == 0),
            "timeout": present & ~robots.finished,
            "collision_ended": present & robots.ended,
            "episode_length": end.length,
            "stuck_end": ((end.length < end.params.max_steps)
                          & ~jnp.all(~present | robots.finished)),
        }
