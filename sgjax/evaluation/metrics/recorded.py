"""Metrics of episodes among recorded people (``recorded:FILE`` scenarios,
:mod:`sgjax.humans.replay`): how far the robots pushed people off their recorded paths, and
how many people they reached. NaN in worlds of simulated pedestrians."""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array

from sgjax.evaluation.metrics.base import Metric, episode_metric
from sgjax.evaluation.metrics.registration import register_metric
from sgjax.evaluation.metrics.step_view import EpisodeEnd


@register_metric
class RecordedPeople(Metric):
    """From the final state's replay books (:class:`sgjax.humans.replay.ReplayState`); no
    accumulator."""

    infos = (
        episode_metric("log_deviation", "m",
                       "mean over the recorded people and the time they are in the scene of "
                       "their distance from where the recording has them at that time (0 for "
                       "ghosts; NaN without recorded people)",
                       "issue 68; SocNavBench's prerecorded agents"),
        episode_metric("log_deviation_max", "m",
                       "largest time-mean distance of one person from their recorded path "
                       "(NaN without recorded people)", "issue 68"),
        episode_metric("people_reached", "count",
                       "recorded people a robot touched (human_replay='pause') or came within "
                       "handover_radius of (human_replay='handover'); 0 for ghosts (NaN "
                       "without recorded people)", "issue 68"),
    )

    def finalize(self, tally: tuple, end: EpisodeEnd) -> dict[str, Array]:
        replay = end.state.humans.replay
        if replay is None:
            nan = jnp.full((), jnp.nan, jnp.float32)
            return {"log_deviation": nan, "log_deviation_max": nan, "people_reached": nan}
        exposure = jnp.sum(replay.exposure)
        mean = jnp.sum(replay.deviation) / jnp.maximum(exposure, 1e-9)
        each = replay.deviation / jnp.maximum(replay.exposure, 1e-9)
        seen = replay.exposure > 0.0
        return {"log_deviation": jnp.where(exposure > 0.0, mean, jnp.nan),
                "log_deviation_max": jnp.where(jnp.any(seen),
                                               jnp.max(jnp.where(seen, each, 0.0)), jnp.nan),
                "people_reached": jnp.sum(replay.reached).astype(jnp.float32)}
