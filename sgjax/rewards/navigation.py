"""Reward terms about getting to the goal: existence, success, collisions, progress, goal
distance, smoothness and preferred speed. Values per robot ``[R]``, natural sign."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import jax.numpy as jnp
from jax import Array

from sgjax.kernels.geometry import safe_norm
from sgjax.rewards.base import REWARDS, RewardTerm
from sgjax.terms.queries import collided
from sgjax.validation import check_bool, check_choice, check_positive

if TYPE_CHECKING:
    from sgjax.terms.contract import TermInput


@REWARDS.register
@dataclasses.dataclass(frozen=True)
class Existence(RewardTerm):
    """-1 for every step a robot ends short of its goal (0 on the step it arrives)."""

    name = "existence"

    def __call__(self, inputs: TermInput) -> Array:
        state = inputs.state
        return -(~state.robots.succeeded).astype(jnp.float32)


@REWARDS.register
@dataclasses.dataclass(frozen=True)
class Success(RewardTerm):
    """+1 on the step a robot reaches its goal, once (SocialGym paid it on every step at the
    goal)."""

    name = "success"

    def __call__(self, inputs: TermInput) -> Array:
        prev, state = inputs.prev, inputs.state
        return (state.robots.succeeded & ~prev.robots.succeeded).astype(jnp.float32)


@REWARDS.register
@dataclasses.dataclass(frozen=True)
class Collision(RewardTerm):
    """-1 on each step a collision begins (with ``per_step``: each step in contact), counting
    the kinds switched on (``robots``, ``walls``, ``humans``); at most -1 per step."""

    name = "collision"
    per_step: bool = False
    robots: bool = True
    walls: bool = True
    humans: bool = True

    def __post_init__(self) -> None:
        for field in ("per_step", "robots", "walls", "humans"):
            check_bool(field, getattr(self, field))

    def __call__(self, inputs: TermInput) -> Array:
        prev, state = inputs.prev, inputs.state
        hit = collided(prev, state, self.robots, self.walls, self.humans, self.per_step)
        return -hit.astype(jnp.float32)


@REWARDS.register
@dataclasses.dataclass(frozen=True)
class Progress(RewardTerm):
    """Metres gained toward the goal this step: straight-line distance before minus after
    (SocialGym's ``GoalDistanceChange``), or with ``along_route`` the gain in arc length along
    the robot's route. ``clip: [low, high]`` clamps it (SocialGym's ``clip`` was ``[0, 1]``)."""

    name = "progress"
    clip: tuple[float, float] | None = None
    along_route: bool = False

    def __post_init__(self) -> None:
        check_bool("along_route", self.along_route)
        if self.clip is not None:
            ok = (isinstance(self.clip, tuple) and len(self.clip) == 2
                  and all(isinstance(v, int | float) for v in self.clip)
                  and self.clip[0] <= self.clip[1])
            if not ok:
                raise ValueError(f"clip must be [low, high] with low <= high, got {self.clip!r}")

    def __call__(self, inputs: TermInput) -> Array:
        prev, state = inputs.prev, inputs.state
        if self.along_route:
            gain = state.progress - prev.progress
        else:
            gain = prev.goal_distance - state.goal_distance
        if self.clip is not None:
            gain = jnp.clip(gain, self.clip[0], self.clip[1])
        return gain


@REWARDS.register
@dataclasses.dataclass(frozen=True)
class GoalDistance(RewardTerm):
    """The distance to the goal after the step: ``form="negative"`` gives ``-d`` (m),
    ``"inverse"`` gives ``1 / max(d, floor)`` (SocialGym's ``GoalDistance``, 1/m)."""

    name = "goal_distance"
    form: str = "negative"
    floor: float = 0.1

    def __post_init__(self) -> None:
        check_choice("form", self.form, ("negative", "inverse"))
        check_positive("floor", self.floor)

    def __call__(self, inputs: TermInput) -> Array:
        state = inputs.state
        d = state.goal_distance
        return -d if self.form == "negative" else 1.0 / jnp.maximum(d, self.floor)


@REWARDS.register
@dataclasses.dataclass(frozen=True)
class VelocityChange(RewardTerm):
    """``-|v_t - v_(t-1)|^2`` of the world-frame velocity ((m/s)^2). SocialGym summed the
    components before squaring, so opposite changes cancelled; this does not."""

    name = "velocity_change"

    def __call__(self, inputs: TermInput) -> Array:
        prev, state = inputs.prev, inputs.state
        dv = state.robots.velocity - prev.robots.velocity
        return -(dv[:, 0] ** 2 + dv[:, 1] ** 2)


@REWARDS.register
@dataclasses.dataclass(frozen=True)
class PreferredVelocity(RewardTerm):
    """``-(|v| - v_pref)^2`` ((m/s)^2) after the step; ``v_pref`` is ``speed`` or, when None,
    the robot's top forward speed."""

    name = "preferred_velocity"
    speed: float | None = None

    def __post_init__(self) -> None:
        if self.speed is not None:
            check_positive("speed", self.speed)

    def __call__(self, inputs: TermInput) -> Array:
        state, params = inputs.state, inputs.params
        v = state.robots.velocity
        preferred = params.robots.max_speed if self.speed is None else self.speed
        return -(safe_norm(v[:, 0], v[:, 1]) - preferred) ** 2
