"""Observation terms about the robot itself: pose, velocity, goal, flags, next waypoint."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import jax.numpy as jnp
from jax import Array

from sgjax.observations.base import OBSERVATIONS, ObservationTerm
from sgjax.observations.columns import Columns
from sgjax.terms.queries import to_robot_frame
from sgjax.validation import check_bool, check_choice, check_int, check_positive

if TYPE_CHECKING:
    from sgjax.terms.contract import TermInput
    from sgjax.types import Layout


def with_past(now: Array, past: Array, steps: int, term: str) -> Array:
    """``[steps, R]``: the current values ``now [R]`` then the latest ``steps - 1`` rows of a
    ``[K - 1, R]`` history, with a clear error if the environment keeps too little (it keeps as
    much as its own observer needs)."""
    if past.shape[0] < steps - 1:
        raise ValueError(f"observation term {term!r} reads {steps} steps, but this environment "
                         f"keeps a history of {past.shape[0] + 1} steps (its observer's "
                         "longest); build the environment with this term in its observations")
    return jnp.concatenate([now[None], past[: steps - 1]], axis=0)


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class Pose(ObservationTerm):
    """World position ``(x, y)`` (m) and, with ``heading``, ``(cos h, sin h)``."""

    name = "pose"
    heading: bool = True

    def __post_init__(self) -> None:
        check_bool("heading", self.heading)

    def columns(self, layout: Layout) -> Columns:
        position = {"position": ("x", "y")}
        heading = {"heading": ("cos_heading", "sin_heading")} if self.heading else {}
        return Columns.grouped({**position, **heading})

    def __call__(self, inputs: TermInput) -> Array:
        r = inputs.state.robots
        parts = [r.x, r.y] + ([jnp.cos(r.heading), jnp.sin(r.heading)] if self.heading else [])
        return jnp.stack(parts, axis=-1)


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class Velocity(ObservationTerm):
    """Own velocity over the last ``history`` steps, latest first: ``frame="body"`` gives
    ``(v_forward, v_lateral)``, ``"world"`` gives ``(vx, vy)`` (m/s); ``turn_rate`` appends
    ``omega`` (rad/s). Size ``history x (2 or 3)``; before the episode's start the history
    repeats the initial (resting) velocity."""

    name = "velocity"
    frame: str = "body"
    history: int = 1  # type: ignore[misc]
    turn_rate: bool = True

    def __post_init__(self) -> None:
        check_choice("frame", self.frame, ("body", "world"))
        check_int("history", self.history)
        check_bool("turn_rate", self.turn_rate)

    def columns(self, layout: Layout) -> Columns:
        names = ("v_forward", "v_lateral") if self.frame == "body" else ("vx", "vy")
        return Columns.plain(*names, *(("omega",) if self.turn_rate else ()),
                             repeat=self.history)

    def __call__(self, inputs: TermInput) -> Array:
        state = inputs.state
        h, k, kin = state.history, self.history, state.robots.kin
        if self.frame == "body":
            pairs = [(kin.v_forward, h.v_forward), (kin.v_lateral, h.v_lateral)]
        else:
            v = state.robots.velocity
            pairs = [(v[:, 0], h.vx), (v[:, 1], h.vy)]
        pairs += [(kin.omega, h.omega)] if self.turn_rate else []
        parts = [with_past(now, past, k, self.name) for now, past in pairs]
        stacked = jnp.stack(parts, axis=-1)  # [k, R, c]
        return jnp.moveaxis(stacked, 0, 1).reshape(stacked.shape[1], -1)


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class Goal(ObservationTerm):
    """The goal: ``frame="world"`` gives its world position ``(gx, gy)``, ``"robot"`` the vector
    to it in the robot's frame (m)."""

    name = "goal"
    frame: str = "robot"

    def __post_init__(self) -> None:
        check_choice("frame", self.frame, ("world", "robot"))

    def columns(self, layout: Layout) -> Columns:
        return Columns.plain("x", "y") if self.frame == "world" else Columns.plain("dx", "dy")

    def __call__(self, inputs: TermInput) -> Array:
        r, route = inputs.state.robots, inputs.state.route
        if self.frame == "world":
            return jnp.stack([route.goal_x, route.goal_y], axis=-1)
        gx, gy = to_robot_frame(r.heading, route.goal_x - r.x, route.goal_y - r.y)
        return jnp.stack([gx, gy], axis=-1)


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class GoalDistance(ObservationTerm):
    """Straight-line distance to the goal (m) over the last ``history`` steps, latest first."""

    name = "goal_distance"
    history: int = 1  # type: ignore[misc]

    def __post_init__(self) -> None:
        check_int("history", self.history)

    def columns(self, layout: Layout) -> Columns:
        return Columns.plain("distance", repeat=self.history)

    def __call__(self, inputs: TermInput) -> Array:
        state = inputs.state
        return with_past(state.goal_distance, state.history.goal_distance, self.history,
                         self.name).T


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class PreferredSpeed(ObservationTerm):
    """The speed the robot would like to travel at (m/s): ``speed``, or the robot's top forward
    speed when ``speed`` is None."""

    name = "preferred_speed"
    speed: float | None = None

    def __post_init__(self) -> None:
        if self.speed is not None:
            check_positive("speed", self.speed)

    def columns(self, layout: Layout) -> Columns:
        return Columns.plain("speed")

    def __call__(self, inputs: TermInput) -> Array:
        top = inputs.params.robots.max_speed
        return (top if self.speed is None else jnp.full_like(top, self.speed))[:, None]


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class CollisionFlag(ObservationTerm):
    """1 if the robot touched a robot, wall or pedestrian during the last step, else 0."""

    name = "collision"

    def columns(self, layout: Layout) -> Columns:
        return Columns.plain("collision")

    def __call__(self, inputs: TermInput) -> Array:
        state = inputs.state
        touching = state.touching_robot | state.touching_wall | state.touching_human
        return touching.astype(jnp.float32)[:, None]


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class SuccessFlag(ObservationTerm):
    """1 once the robot has reached its goal, else 0."""

    name = "success"

    def columns(self, layout: Layout) -> Columns:
        return Columns.plain("success")

    def __call__(self, inputs: TermInput) -> Array:
        return inputs.state.robots.succeeded.astype(jnp.float32)[:, None]


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class Waypoint(ObservationTerm):
    """The next node of the robot's route ahead of its progress, in the robot's frame (m); the
    goal once every node is behind."""

    name = "waypoint"

    def columns(self, layout: Layout) -> Columns:
        return Columns.plain("dx", "dy")

    def __call__(self, inputs: TermInput) -> Array:
        state = inputs.state
        r, route = state.robots, state.route
        ahead = route.cum_length > state.progress[:, None] + 1e-3  # [R, L], monotone
        before = jnp.concatenate([jnp.zeros_like(ahead[:, :1]), ahead[:, :-1]], axis=1)
        first = (ahead & ~before).astype(jnp.float32)
        none_ahead = 1.0 - jnp.sum(first, axis=1)
        wx = jnp.sum(first * route.x, axis=1) + none_ahead * route.goal_x
        wy = jnp.sum(first * route.y, axis=1) + none_ahead * route.goal_y
        dx, dy = to_robot_frame(r.heading, wx - r.x, wy - r.y)
        return jnp.stack([dx, dy], axis=-1)


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class TimeLeft(ObservationTerm):
    """Fraction of the episode's time limit still left, in [0, 1] (lets a policy see truncation
    coming)."""

    name = "time_left"

    def columns(self, layout: Layout) -> Columns:
        return Columns.plain("fraction")

    def __call__(self, inputs: TermInput) -> Array:
        time, steps = inputs.state.time, inputs.params.max_steps
        left = 1.0 - time.astype(jnp.float32) / steps.astype(jnp.float32)
        return jnp.broadcast_to(jnp.clip(left, 0.0, 1.0), (inputs.layout.max_agents, 1))
