"""Smoothness metrics: velocity and turn-rate changes, acceleration and jerk."""

from __future__ import annotations

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.evaluation.metrics.base import Metric, known, robot_metric
from sgjax.evaluation.metrics.constants import MetricConstants
from sgjax.evaluation.metrics.registration import register_metric
from sgjax.evaluation.metrics.step_view import EpisodeEnd, StepView
from sgjax.kernels.geometry import safe_norm


@struct.dataclass
class SmoothnessTally:
    """``[R]`` each unless noted; sums and maxima over active steps."""

    dv_sum: Array  # m/s
    dv_max: Array  # m/s
    domega_sum: Array  # rad/s
    accel_sum: Array  # m/s^2
    accel_max: Array  # m/s^2
    jerk_sum: Array  # m/s^3
    jerk_max: Array  # m/s^3
    jerk_steps: Array  # int32: steps with a jerk (an acceleration on the step before)
    last_accel: Array  # [R, 2] m/s^2: the acceleration on the last active step
    has_accel: Array  # bool: there was one


@register_metric
class Smoothness(Metric):
    """How smoothly each robot drove: changes of its world velocity vector and turn rate per
    step, acceleration ``|dv| / dt`` and jerk ``|da| / dt``."""

    infos = (
        robot_metric("velocity_change_sum", "m/s",
                     "sum over active steps of |v(t+1) - v(t)| (world velocity vectors)",
                     "socialnav.md C1; SocialGym 2.0 avg_velocity_delta used scalar speeds"),
        robot_metric("velocity_change_max", "m/s",
                     "max over active steps of |v(t+1) - v(t)|: the paper's Max delta-V",
                     "SocialGym 2.0 paper Table 3"),
        robot_metric("turn_rate_change_sum", "rad/s",
                     "sum over active steps of |omega(t+1) - omega(t)|", "socialnav.md C1"),
        robot_metric("acceleration_mean", "m/s^2",
                     "mean over active steps of |v(t+1) - v(t)| / dt", "SocNavGym, social-jym"),
        robot_metric("acceleration_max", "m/s^2", "max of the same", "SocNavGym"),
        robot_metric("jerk_mean", "m/s^3",
                     "mean over consecutive active steps of |a(t+1) - a(t)| / dt",
                     "SocNavGym, SEAN"),
        robot_metric("jerk_max", "m/s^3", "max of the same", "SocNavGym"),
    )

    def start(self, num_robots: int, num_zones: int, constants: MetricConstants
              ) -> SmoothnessTally:
        zf = jnp.zeros(num_robots, jnp.float32)
        return SmoothnessTally(
            dv_sum=zf, dv_max=zf, domega_sum=zf, accel_sum=zf, accel_max=zf, jerk_sum=zf,
            jerk_max=zf, jerk_steps=jnp.zeros(num_robots, jnp.int32),
            last_accel=jnp.zeros((num_robots, 2), jnp.float32),
            has_accel=jnp.zeros(num_robots, bool))

    def update(self, tally: SmoothnessTally, view: StepView) -> SmoothnessTally:
        dt, was_active = view.dt, view.was_active
        dv_norm = view.velocity_change_norm
        accel = view.velocity_change / dt
        jerk_vec = (accel - tally.last_accel) / dt
        jerk = safe_norm(jerk_vec[:, 0], jerk_vec[:, 1])
        jerk_ok = was_active & tally.has_accel
        domega = jnp.abs(view.state.robots.kin.omega - view.prev.robots.kin.omega)
        return SmoothnessTally(
            dv_sum=view.add(tally.dv_sum, dv_norm),
            dv_max=view.most(tally.dv_max, dv_norm),
            domega_sum=view.add(tally.domega_sum, domega),
            accel_sum=view.add(tally.accel_sum, dv_norm / dt),
            accel_max=view.most(tally.accel_max, dv_norm / dt),
            jerk_sum=view.add(tally.jerk_sum, jerk, jerk_ok),
            jerk_max=view.most(tally.jerk_max, jerk, jerk_ok),
            jerk_steps=view.add(tally.jerk_steps, 1, jerk_ok),
            last_accel=jnp.where(was_active[:, None], accel, tally.last_accel),
            has_accel=tally.has_accel | was_active,
        )

    def finalize(self, tally: SmoothnessTally, end: EpisodeEnd) -> dict[str, Array]:
        jerked = tally.jerk_steps > 0
        return {
            "velocity_change_sum": tally.dv_sum,
            "velocity_change_max": tally.dv_max,
            "turn_rate_change_sum": tally.domega_sum,
            "acceleration_mean": tally.accel_sum / end.steps,
            "acceleration_max": tally.accel_max,
            "jerk_mean": known(tally.jerk_sum / jnp.maximum(tally.jerk_steps, 1), jerked),
            "jerk_max": known(tally.jerk_max, jerked),
        }
