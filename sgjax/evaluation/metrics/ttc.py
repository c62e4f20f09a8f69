"""Time-to-collision metrics: the least time to collision at constant velocities, and how
often it is short."""

from __future__ import annotations

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.evaluation.metrics.base import Metric, robot_metric
from sgjax.evaluation.metrics.constants import MetricConstants
from sgjax.evaluation.metrics.registration import register_metric
from sgjax.evaluation.metrics.step_view import EpisodeEnd, StepView
from sgjax.kernels.contacts import CONTACT_GAP

# Bodies whose gap is at most the simulator's contact gap (10 um) are touching:
# time-to-collision 0. Robots that the bumpers stopped against each other rest within about
# 4e-7 m of touching either way in float32; without a tolerance half of them read as apart and
# "never colliding". One constant with the contact step, so that a metric and the bumpers agree
# on what touching is.
TOUCHING = CONTACT_GAP


def time_to_collision(dpx: Array, dpy: Array, dvx: Array, dvy: Array, reach: Array) -> Array:
    """Smallest ``tau >= 0`` with ``|dp + tau dv| = reach`` (s); 0 when already within
    ``reach + TOUCHING`` (touching or overlapping), inf when the bodies never get that close.
    Element-wise (m, m/s)."""
    a = dvx * dvx + dvy * dvy
    b = 2.0 * (dpx * dvx + dpy * dvy)
    distance_sq = dpx * dpx + dpy * dpy
    c = distance_sq - reach * reach
    disc = b * b - 4.0 * a * c
    closing = (b < 0.0) & (disc >= 0.0) & (a > 1e-12)
    root = (-b - jnp.sqrt(jnp.maximum(disc, 0.0))) / (2.0 * jnp.where(closing, a, 1.0))
    touching = distance_sq <= jnp.square(reach + TOUCHING)
    return jnp.where(touching, 0.0, jnp.where(closing, root, jnp.inf))


@struct.dataclass
class TtcTally:
    """``[R]`` each."""

    min_ttc: Array  # s
    low_steps: Array  # int32: active steps with time-to-collision below ttc_threshold


@register_metric
class TimeToCollision(Metric):
    """Each robot's time-to-collision with the bodies it meets (:attr:`StepView.others`),
    everybody keeping their present velocity (parked robots at rest), after each active
    step."""

    infos = (
        robot_metric("min_ttc", "s",
                     "min over active steps of the time-to-collision with any other body at "
                     "constant velocities (smallest tau >= 0 with |dp + tau dv| = r_i + r_j; 0 "
                     "when touching: a gap of at most 1e-5 m), capped at ttc_cap",
                     "socialnav.md C1"),
        robot_metric("ttc_below_threshold", "fraction",
                     "fraction of active steps with time-to-collision < ttc_threshold",
                     "socialnav.md C1"),
    )

    def start(self, num_robots: int, num_zones: int, constants: MetricConstants) -> TtcTally:
        return TtcTally(min_ttc=jnp.full(num_robots, constants.ttc_cap),
                        low_steps=jnp.zeros(num_robots, jnp.int32))

    def update(self, tally: TtcTally, view: StepView) -> TtcTally:
        robots, b, c = view.state.robots, view.bodies, view.constants
        x, y, v = robots.x, robots.y, robots.velocity
        radius = view.params.robots.radius
        ttc = time_to_collision(b.x[None, :] - x[:, None], b.y[None, :] - y[:, None],
                                b.vx[None, :] - v[:, 0:1], b.vy[None, :] - v[:, 1:2],
                                b.radius[None, :] + radius[:, None])
        ttc = jnp.min(jnp.where(view.others, ttc, jnp.inf), axis=1, initial=jnp.inf)
        ttc = jnp.minimum(ttc, c.ttc_cap)
        return TtcTally(min_ttc=view.least(tally.min_ttc, ttc),
                        low_steps=view.add(tally.low_steps, 1,
                                           view.was_active & (ttc < c.ttc_threshold)))

    def finalize(self, tally: TtcTally, end: EpisodeEnd) -> dict[str, Array]:
        return {"min_ttc": tally.min_ttc, "ttc_below_threshold": tally.low_steps / end.steps}
