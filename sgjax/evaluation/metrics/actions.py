"""Action metrics: how often a policy's action was invalid and replaced by the neutral one."""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array

from sgjax.evaluation.metrics.base import Metric, robot_metric
from sgjax.evaluation.metrics.constants import MetricConstants
from sgjax.evaluation.metrics.registration import register_metric
from sgjax.evaluation.metrics.step_view import EpisodeEnd, StepView


@register_metric
class InvalidActions(Metric):
    """Steps whose action the environment refused (``info["invalid_action"]``: a NaN or
    infinite continuous command, a GO/STOP value other than 0 and 1) and replaced by the
    neutral action (zero command, STOP): a policy that produces NaN shows in every table
    instead of silently standing still."""

    infos = (
        robot_metric("invalid_actions", "count",
                     "steps, while active, at which the robot's action was invalid (NaN or "
                     "infinite continuous command, GO/STOP other than 0 or 1) and the neutral "
                     "action was taken instead; summed over robots",
                     "sgjax: the environment's info['invalid_action'] (SocialNavEnv.step_env)",
                     reduce="sum"),
    )

    def start(self, num_robots: int, num_zones: int, constants: MetricConstants) -> Array:
        return jnp.zeros(num_robots, jnp.int32)

    def update(self, tally: Array, view: StepView) -> Array:
        # (hand-built steps of tests may leave the flag out: no invalid action then)
        invalid = view.info.get("invalid_action", jnp.zeros_like(view.was_active))
        return view.add(tally, 1, view.was_active & invalid)

    def finalize(self, tally: Array, end: EpisodeEnd) -> dict[str, Array]:
        return {"invalid_actions": tally}
