"""The k nearest other bodies (robots and pedestrians) in each robot's frame."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp
from jax import Array

from sgjax.kernels.geometry import safe_norm
from sgjax.observations.base import OBSERVATIONS, ObservationTerm
from sgjax.observations.columns import Columns
from sgjax.terms.queries import gather_bodies, line_of_sight, to_robot_frame
from sgjax.validation import check_bool, check_int, check_positive

if TYPE_CHECKING:
    from sgjax.terms.contract import TermInput
    from sgjax.types import EnvParams, EnvState, Layout

# Per-other feature groups and the names of their columns (a feature's width is their number).
FEATURES: dict[str, tuple[str, ...]] = {
    "position": ("dx", "dy"),  # m, robot frame
    "distance": ("gap",),  # body-to-body gap (m): centre distance minus both radii
    "heading": ("cos_heading", "sin_heading"),  # of the other's heading relative to the robot's
    "velocity": ("vx", "vy"),  # the other's velocity (or relative velocity), robot frame, m/s
    "radius": ("radius",),  # m
    "kind": ("is_human",),  # 1 = pedestrian, 0 = robot
    "mask": ("mask",),  # 1 = a real, visible body in this slot; 0 = padding
    "goal": ("goal_dx", "goal_dy"),  # m, robot frame, to the other robot's goal; 0 for people
}
# The features seen when none are named, in output order (every feature but "goal").
DEFAULT_FEATURES = ("position", "distance", "heading", "velocity", "radius", "kind", "mask")
_FAR = 1.0e9


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class Others(ObservationTerm):
    """The ``k`` nearest other robots and pedestrians, nearest first, each described by
    ``features`` (see ``FEATURES``) in the robot's frame; empty slots are zeros with mask 0.

    ``robots`` / ``humans`` choose who is seen; ``line_of_sight`` hides bodies whose centre is
    behind a wall (SocialGym's ``partially_observable``); ``max_range`` (m) hides farther ones;
    ``relative_velocity`` reports ``v_other - v_self`` instead of ``v_other``. ``features``
    defaults to ``DEFAULT_FEATURES``; ``goal`` (where another robot is going) is asked for by
    name. Size ``k x width``: ``columns(layout)`` has ``k`` blocks (bodies, nearest first) of
    the ``features``' columns (``FEATURES``).
    """

    name = "others"
    k: int = 4
    features: tuple[str, ...] = DEFAULT_FEATURES
    robots: bool = True
    humans: bool = True
    line_of_sight: bool = False
    max_range: float | None = None
    relative_velocity: bool = False

    def __post_init__(self) -> None:
        check_int("k", self.k)
        if isinstance(self.features, str) or not self.features:
            raise ValueError(f"features must be a non-empty list of {list(FEATURES)}, "
                             f"got {self.features!r}")
        for f in self.features:
            if f not in FEATURES:
                raise ValueError(f"features: unknown feature {f!r}; valid: {list(FEATURES)}")
        if len(set(self.features)) != len(self.features):
            raise ValueError(f"features: each feature may appear once, got {list(self.features)}")
        for field in ("robots", "humans", "line_of_sight", "relative_velocity"):
            check_bool(field, getattr(self, field))
        if self.max_range is not None:
            check_positive("max_range", self.max_range)

    @property
    def width(self) -> int:
        """Columns per body."""
        return sum(len(FEATURES[f]) for f in self.features)

    def most_seen(self, layout: Layout) -> int:
        """The most slots that can hold a body in an environment of ``layout``: the other robot
        slots and the pedestrian slots it sees, at most ``k``. Slots past it are always empty
        (bodies come nearest first, empty slots last)."""
        count = (layout.max_agents - 1 if self.robots else 0) + (
            layout.max_humans if self.humans else 0)
        return min(self.k, max(count, 0))

    def columns(self, layout: Layout) -> Columns:
        """``k`` blocks (bodies, nearest first) of the chosen features' columns; ``filled`` is
        :meth:`most_seen`."""
        return Columns.grouped({f: FEATURES[f] for f in self.features}, repeat=self.k,
                               filled=self.most_seen(layout))

    def nearest(self, state: EnvState, params: EnvParams, layout: Layout
                ) -> tuple[Array, dict[str, Array]]:
        """``(visible [R, k] bool, features {name: [R, k, width]})`` of the k nearest."""
        r = state.robots
        bodies = gather_bodies(state, params, robots=self.robots, humans=self.humans)
        num_robots = layout.max_agents
        count = bodies.x.shape[0]
        dxw = bodies.x[None, :] - r.x[:, None]  # [R, B]
        dyw = bodies.y[None, :] - r.y[:, None]
        centre = safe_norm(dxw, dyw)
        visible = jnp.broadcast_to(bodies.in_world[None, :], (num_robots, count))
        if self.robots:  # a robot does not see itself
            visible = visible & ~jnp.eye(num_robots, count, dtype=bool)
        if self.max_range is not None:
            visible = visible & (centre <= self.max_range)
        if self.line_of_sight:
            visible = visible & line_of_sight(r.x[:, None], r.y[:, None], bodies.x[None, :],
                                              bodies.y[None, :], params, self.max_range)
        if count < self.k:  # pad so that top_k has k candidates
            pad = self.k - count
            centre = jnp.pad(centre, ((0, 0), (0, pad)))
            visible = jnp.pad(visible, ((0, 0), (0, pad)))
        order_key = jnp.where(visible, centre, _FAR)
        _, index = jax.lax.top_k(-order_key, self.k)  # [R, k], nearest first, stable on ties
        chosen = jnp.take_along_axis(visible, index, axis=1)

        def pick(values: Array) -> Array:  # [R, B] -> [R, k]
            if count < self.k:
                values = jnp.pad(values, ((0, 0), (0, self.k - count)))
            return jnp.where(chosen, jnp.take_along_axis(values, index, axis=1), 0.0)

        def each(v: Array) -> Array:
            return jnp.broadcast_to(v[None, :], (num_robots, count))

        c, s = jnp.cos(r.heading)[:, None], jnp.sin(r.heading)[:, None]
        own = r.velocity
        vx, vy = each(bodies.vx), each(bodies.vy)
        if self.relative_velocity:
            vx, vy = vx - own[:, :1], vy - own[:, 1:]
        rel_cos = c * each(bodies.cos_h) + s * each(bodies.sin_h)
        rel_sin = c * each(bodies.sin_h) - s * each(bodies.cos_h)
        px, py = to_robot_frame(r.heading[:, None], dxw, dyw)
        is_robot = each(bodies.is_human) == 0.0
        gx, gy = to_robot_frame(r.heading[:, None],
                                jnp.where(is_robot, each(bodies.goal_x) - r.x[:, None], 0.0),
                                jnp.where(is_robot, each(bodies.goal_y) - r.y[:, None], 0.0))
        qx, qy = to_robot_frame(r.heading[:, None], vx, vy)
        radius = each(bodies.radius)
        columns = {
            "position": [px, py],
            "distance": [centre[:, :count] - radius - params.robots.radius[:, None]],
            "heading": [rel_cos, rel_sin],
            "velocity": [qx, qy],
            "radius": [radius],
            "kind": [each(bodies.is_human)],
            "mask": [jnp.ones((num_robots, count))],
            "goal": [gx, gy],
        }
        feats = {name: jnp.stack([pick(v) for v in columns[name]], axis=-1)
                 for name in self.features}
        return chosen, feats

    def __call__(self, inputs: TermInput) -> Array:
        _, feats = self.nearest(inputs.state, inputs.params, inputs.layout)
        stacked = jnp.concatenate([feats[name] for name in self.features], axis=-1)
        return stacked.reshape(inputs.layout.max_agents, -1)
