"""Social reward terms: CADRL's proximity penalty, personal space around pedestrians, and the
SA-CADRL social norms (right-handed: pass, overtake and cross the way pedestrians keep right).

Geometry is in the robot's frame (x forward, y to the left); ``dh`` is the other's heading
minus the robot's, wrapped. Pedestrians face along their velocity. Bodies counted: other robots
in the world (active, settling, or parked at rest) and active pedestrians.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import jax.numpy as jnp
from jax import Array

from sgjax.kernels.geometry import polynomial_atan2, safe_norm
from sgjax.rewards.base import REWARDS, RewardTerm
from sgjax.terms.queries import body_gaps, gather_bodies, to_robot_frame
from sgjax.validation import check_bool, check_positive

if TYPE_CHECKING:
    from sgjax.terms.contract import TermInput
    from sgjax.types import EnvParams, EnvState, Layout

@REWARDS.register
@dataclasses.dataclass(frozen=True)
class Proximity(RewardTerm):
    """CADRL's discomfort penalty: ``-(threshold - d_min) / 2`` when the nearest body gap
    ``d_min`` (m, floored at 0) is under ``threshold`` (CADRL: 0.2 m, so -0.1 at contact),
    else 0."""

    name = "proximity"
    threshold: float = 0.2
    robots: bool = True
    humans: bool = True

    def __post_init__(self) -> None:
        check_positive("threshold", self.threshold)
        check_bool("robots", self.robots)
        check_bool("humans", self.humans)

    def __call__(self, inputs: TermInput) -> Array:
        state, params, layout = inputs.state, inputs.params, inputs.layout
        gaps = body_gaps(state, params, layout, self.robots, self.humans)
        if gaps.shape[1] == 0:
            return jnp.zeros(layout.max_agents)
        nearest = jnp.maximum(jnp.min(gaps, axis=1), 0.0)
        return -jnp.maximum(self.threshold - nearest, 0.0) / 2.0


@REWARDS.register
@dataclasses.dataclass(frozen=True)
class PersonalSpace(RewardTerm):
    """``-sum over pedestrians of max(0, 1 - gap / radius)``: 0 outside ``radius`` (m, body to
    body; 0.45 m is the intimate zone of ``socialnav.md`` C), -1 per pedestrian touching."""

    name = "personal_space"
    radius: float = 0.45

    def __post_init__(self) -> None:
        check_positive("radius", self.radius)

    def __call__(self, inputs: TermInput) -> Array:
        state, params, layout = inputs.state, inputs.params, inputs.layout
        gaps = body_gaps(state, params, layout, robots=False, humans=True)
        intrusion = jnp.maximum(1.0 - jnp.maximum(gaps, 0.0) / self.radius, 0.0)
        return -jnp.sum(intrusion, axis=1)


def _norm_geometry(state: EnvState, params: EnvParams, layout: Layout
                   ) -> tuple[Array, Array, Array, Array, Array, Array]:
    """``(px, py, dh, bearing, other_speed, there)`` each ``[R, B]`` for the social norms."""
    r = state.robots
    b = gather_bodies(state, params)
    px, py = to_robot_frame(r.heading[:, None], b.x[None, :] - r.x[:, None],
                            b.y[None, :] - r.y[:, None])
    c, s = jnp.cos(r.heading)[:, None], jnp.sin(r.heading)[:, None]
    dh = polynomial_atan2(c * b.sin_h[None, :] - s * b.cos_h[None, :],
                          c * b.cos_h[None, :] + s * b.sin_h[None, :])
    bearing = polynomial_atan2(py, px)
    other_speed = jnp.broadcast_to(safe_norm(b.vx, b.vy)[None, :], px.shape)
    there = b.in_world[None, :] & ~jnp.eye(layout.max_agents, b.x.shape[0], dtype=bool)
    return px, py, dh, bearing, other_speed, there


@dataclasses.dataclass(frozen=True)
class SocialNorm(RewardTerm):
    """Shared option: norms apply only while the robot is farther than ``goal_distance`` (m)
    from its goal (SA-CADRL: 3 m)."""

    goal_distance: float = 3.0

    def __post_init__(self) -> None:
        check_positive("goal_distance", self.goal_distance, allow_zero=True)

    def violations(self, px: Array, py: Array, dh: Array, bearing: Array, own_speed: Array,
                   other_speed: Array) -> Array:
        raise NotImplementedError

    def __call__(self, inputs: TermInput) -> Array:
        state, params, layout = inputs.state, inputs.params, inputs.layout
        px, py, dh, bearing, other_speed, there = _norm_geometry(state, params, layout)
        v = state.robots.velocity
        own_speed = safe_norm(v[:, 0], v[:, 1])[:, None]
        bad = self.violations(px, py, dh, bearing, own_speed, other_speed) & there
        far = state.goal_distance > self.goal_distance
        return -jnp.sum(bad, axis=1).astype(jnp.float32) * far


@REWARDS.register
@dataclasses.dataclass(frozen=True)
class SocialNormPass(SocialNorm):
    """-1 per oncoming body (``|dh| > 3 pi / 4``) ahead on the robot's right
    (``1 < px < 4``, ``-2 < py < 0``): passing it would be on the wrong side."""

    name = "social_norm_pass"

    def violations(self, px, py, dh, bearing, own_speed, other_speed):  # noqa: ANN001, ANN201
        return ((px > 1.0) & (px < 4.0) & (py > -2.0) & (py < 0.0)
                & (jnp.abs(dh) > 0.75 * math.pi))


@REWARDS.register
@dataclasses.dataclass(frozen=True)
class SocialNormOvertake(SocialNorm):
    """-1 per slower body going the same way (``|dh| < pi / 4``) ahead on the robot's left
    (``0 < px < 3``, ``0 < py < 1``): overtaking it would be on its right. (SocialGym tested
    ``|dh| > pi / 4``, which is not "the same way".)"""

    name = "social_norm_overtake"

    def violations(self, px, py, dh, bearing, own_speed, other_speed):  # noqa: ANN001, ANN201
        return ((px > 0.0) & (px < 3.0) & (py > 0.0) & (py < 1.0)
                & (jnp.abs(dh) < 0.25 * math.pi) & (own_speed > other_speed))


@REWARDS.register
@dataclasses.dataclass(frozen=True)
class SocialNormCross(SocialNorm):
    """-1 per body within 2 m on the robot's left (bearing > 0) crossing its path from left to
    right (``-3 pi / 4 < dh < -pi / 4``)."""

    name = "social_norm_cross"

    def violations(self, px, py, dh, bearing, own_speed, other_speed):  # noqa: ANN001, ANN201
        near = safe_norm(px, py) < 2.0
        return near & (bearing > 0.0) & (dh > -0.75 * math.pi) & (dh < -0.25 * math.pi)
