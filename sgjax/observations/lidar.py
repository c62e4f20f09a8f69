"""A 2-D lidar: beams cast from each robot against walls, other robots and pedestrians."""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp
from jax import Array

from sgjax.kernels.contacts import Walls
from sgjax.kernels.walls_along import uses_lists_along, walls_along
from sgjax.observations.base import OBSERVATIONS, ObservationTerm
from sgjax.observations.columns import Columns
from sgjax.terms.queries import gather_bodies
from sgjax.validation import check_bool, check_int, check_positive

if TYPE_CHECKING:
    from sgjax.terms.contract import TermInput
    from sgjax.types import Layout


def beam_angles(beams: int, fov: float) -> Array:
    """Beam directions (rad) in the robot frame: evenly over ``fov``, centred on straight ahead
    (a full circle has no repeated beam)."""
    if fov >= 2.0 * math.pi - 1e-9:
        return jnp.arange(beams) * (2.0 * math.pi / beams) - math.pi
    if beams == 1:
        return jnp.zeros(1)
    return jnp.linspace(-fov / 2.0, fov / 2.0, beams)


def ray_segment_hits(px: Array, py: Array, ux: Array, uy: Array, ax: Array, ay: Array,
                     bx: Array, by: Array) -> Array:
    """Distance along unit rays ``p + t u`` to segments ``a-b`` (broadcast), ``inf`` if missed."""
    ex, ey = bx - ax, by - ay
    denom = ux * ey - uy * ex
    ok = jnp.abs(denom) > 1e-12
    inv = 1.0 / jnp.where(ok, denom, 1.0)
    wx, wy = ax - px, ay - py
    t = (wx * ey - wy * ex) * inv
    s = (wx * uy - wy * ux) * inv
    hit = ok & (t >= 0.0) & (s >= 0.0) & (s <= 1.0)
    return jnp.where(hit, t, jnp.inf)


def ray_disc_hits(px: Array, py: Array, ux: Array, uy: Array, cx: Array, cy: Array,
                  radius: Array) -> Array:
    """Distance along unit rays to the first point of discs (broadcast); 0 from inside a disc,
    ``inf`` if missed."""
    wx, wy = cx - px, cy - py
    b = wx * ux + wy * uy
    c = wx * wx + wy * wy - radius * radius
    disc = b * b - c
    t = b - jnp.sqrt(jnp.where(disc > 0.0, disc, 1.0))  # no inf gradient from sqrt(0)
    inside = c <= 0.0
    hit = inside | ((disc >= 0.0) & (t >= 0.0))
    return jnp.where(inside, 0.0, jnp.where(hit, t, jnp.inf))


def wall_distances(m: Walls, px: Array, py: Array, ux: Array, uy: Array, length: float
                   ) -> Array:
    """Distance (m) along each ray from ``(px, py)`` along the unit ``(ux, uy)`` (broadcast
    shapes ``...``) to the nearest wall, ``inf`` if none; exact up to ``length`` m (beyond it a
    farther wall may be missed: callers cap there). Building floors read the walls from the
    map's cell lists along the ray (:mod:`sgjax.kernels.walls_along`), other maps test every
    wall."""
    if uses_lists_along(m, length):
        index = walls_along(m, px, py, ux, uy, length)  # [..., K]
        hits = ray_segment_hits(px[..., None], py[..., None], ux[..., None], uy[..., None],
                                m.wall_x1[index], m.wall_y1[index], m.wall_x2[index],
                                m.wall_y2[index])
        valid = m.wall_valid[index]
    else:
        hits = ray_segment_hits(px[..., None], py[..., None], ux[..., None], uy[..., None],
                                m.wall_x1, m.wall_y1, m.wall_x2, m.wall_y2)
        valid = m.wall_valid
    return jnp.min(jnp.where(valid, hits, jnp.inf), axis=-1)


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class Lidar(ObservationTerm):
    """``beams`` ranges (m) over ``fov`` (rad, default a full circle) from the robot's centre,
    against walls (:func:`wall_distances`), other robots and pedestrians, capped at
    ``range``. ``noise`` (m) adds Gaussian noise before the cap (SocialGym: 0.01). Beam
    ``i`` points at ``heading + beam_angles(beams, fov)[i]``."""

    name = "lidar"
    beams: int = 16
    range: float = 5.0
    fov: float = 2.0 * math.pi
    noise: float = 0.0
    robots: bool = True
    humans: bool = True

    needs_key = True

    def __post_init__(self) -> None:
        check_int("beams", self.beams)
        check_positive("range", self.range)
        check_positive("fov", self.fov)
        if self.fov > 2.0 * math.pi + 1e-9:
            raise ValueError(f"fov must be at most 2 pi rad, got {self.fov}")
        check_positive("noise", self.noise, allow_zero=True)
        check_bool("robots", self.robots)
        check_bool("humans", self.humans)

    def columns(self, layout: Layout) -> Columns:
        """One block per beam: ``range[i]``."""
        return Columns.plain("range", repeat=self.beams)

    def __call__(self, inputs: TermInput) -> Array:
        state, params, layout = inputs.state, inputs.params, inputs.layout
        r, m = state.robots, params.map
        angle = r.heading[:, None] + beam_angles(self.beams, self.fov)[None, :]  # [R, N]
        ux, uy = jnp.cos(angle), jnp.sin(angle)
        px, py = r.x[:, None, None], r.y[:, None, None]
        # walls beyond the cap are never read (6 sigma of noise past it: noise could bring one
        # under the cap)
        nearest = wall_distances(m, r.x[:, None], r.y[:, None], ux, uy,
                                 self.range + 6.0 * self.noise)  # [R, N]
        bodies = gather_bodies(state, params, robots=self.robots, humans=self.humans)
        if bodies.x.shape[0]:
            hits = ray_disc_hits(px, py, ux[..., None], uy[..., None], bodies.x, bodies.y,
                                 bodies.radius)  # [R, N, B]
            seen = bodies.in_world[None, :]
            if self.robots:
                seen = seen & ~jnp.eye(layout.max_agents, bodies.x.shape[0], dtype=bool)
            hits = jnp.where(seen[:, None, :], hits, jnp.inf)
            nearest = jnp.minimum(nearest, jnp.min(hits, axis=-1))
        if self.noise > 0.0:
            nearest = nearest + self.noise * jax.random.normal(inputs.key, nearest.shape)
        return jnp.clip(nearest, 0.0, self.range)
