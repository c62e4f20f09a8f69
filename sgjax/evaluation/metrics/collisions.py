"""Collision metrics: onsets of contact (the first step of each), by kind, from the final
state's counts (the environment counts them in the step)."""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array

from sgjax.evaluation.metrics.base import Metric, episode_metric, robot_metric
from sgjax.evaluation.metrics.registration import register_metric
from sgjax.evaluation.metrics.step_view import EpisodeEnd


@register_metric
class Collisions(Metric):
    """Collision onsets per robot (all kinds, robot, pedestrian, wall) and whether the episode
    had any; no accumulator."""

    infos = (
        robot_metric("collisions", "count",
                     "collision onsets (steps a contact starts) of any kind, summed over the "
                     "episode's robots: the paper's Coll. Rate",
                     "SocialGym 2.0 `collisions` (rising edges)", reduce="sum"),
        robot_metric("collisions_robot", "count", "robot-robot collision onsets, summed",
                     "SocialGym 2.0", reduce="sum"),
        robot_metric("collisions_human", "count", "robot-pedestrian collision onsets, summed",
                     "socialnav.md C1", reduce="sum"),
        robot_metric("collisions_wall", "count", "robot-wall collision onsets, summed",
                     "socialnav.md C1", reduce="sum"),
        episode_metric("collision_episode", "fraction",
                       "the episode had at least one collision onset",
                       "socialnav.md C1 (Collision rate)", binary=True),
    )

    def finalize(self, tally: tuple, end: EpisodeEnd) -> dict[str, Array]:
        counts = end.state.collisions
        return {
            "collisions": end.collisions,
            "collisions_robot": counts.robot,
            "collisions_human": counts.human,
            "collisions_wall": counts.wall,
            "collision_episode": jnp.any(end.present & (end.collisions > 0)),
        }
