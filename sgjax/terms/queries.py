"""Queries of the state that several terms (observations, rewards, enders, metrics) share:
frames, the bodies a robot can see, gaps between bodies and collision onsets.

Shapes: ``R`` robots, ``B`` bodies (robots first, then pedestrians); distances in m.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
from jax import Array

from sgjax.kernels.geometry import safe_norm
from sgjax.kernels.walls_along import uses_lists_along, walls_along
from sgjax.types import EnvParams, EnvState, Layout

FAR = 1.0e6  # m: the gap reported for bodies that are not there


def to_robot_frame(heading: Array, dx: Array, dy: Array) -> tuple[Array, Array]:
    """Rotate world vectors into each robot's frame (x forward, y to the left)."""
    c, s = jnp.cos(heading), jnp.sin(heading)
    return c * dx + s * dy, -s * dx + c * dy


@dataclasses.dataclass(frozen=True)
class Bodies:
    """Everything another robot can observe: ``[B]`` each (robots first, then pedestrians)."""

    x: Array
    y: Array
    cos_h: Array
    sin_h: Array
    vx: Array
    vy: Array
    radius: Array
    goal_x: Array  # m, world: a robot's goal; 0 for a pedestrian
    goal_y: Array
    is_human: Array  # float 0/1
    in_world: Array  # bool: there (a robot active, settling or parked; an active pedestrian)


def gather_bodies(state: EnvState, params: EnvParams, robots: bool = True,
                  humans: bool = True) -> Bodies:
    """Robots in the world (active, settling, or parked at rest) and active pedestrians as one
    body list. Pedestrians face along their velocity (+x when standing)."""
    r, h = state.robots, state.humans
    vel = r.body_velocity
    parts = []
    if robots:
        parts.append((r.x, r.y, jnp.cos(r.heading), jnp.sin(r.heading), vel[:, 0], vel[:, 1],
                      params.robots.radius, state.route.goal_x, state.route.goal_y,
                      jnp.zeros_like(r.x), r.in_world))
    if humans and h.x.shape[0]:
        speed = safe_norm(h.vx, h.vy)
        moving = speed > 1e-3
        inv = 1.0 / jnp.where(moving, speed, 1.0)
        parts.append((h.x, h.y, jnp.where(moving, h.vx * inv, 1.0),
                      jnp.where(moving, h.vy * inv, 0.0), h.vx, h.vy,
                      jnp.broadcast_to(params.humans.radius, h.x.shape), jnp.zeros_like(h.x),
                      jnp.zeros_like(h.x), jnp.ones_like(h.x), h.active))
    if not parts:
        empty = jnp.zeros((0,), jnp.float32)
        return Bodies(*(empty,) * 10, in_world=jnp.zeros((0,), bool))
    columns = [jnp.concatenate(c) for c in zip(*parts, strict=True)]
    return Bodies(*columns)


def line_of_sight(px: Array, py: Array, qx: Array, qy: Array, params: EnvParams,
                  length: float | None = None) -> Array:
    """Whether segments p-q (broadcast shapes ``S``) cross no wall; returns bool ``S``. With
    ``length`` (m), segments longer than it may see through walls beyond it (callers hide
    those bodies anyway): building floors then read the walls from the map's cell lists along
    each segment (:mod:`sgjax.kernels.walls_along`) instead of testing every wall."""
    m = params.map
    if uses_lists_along(m, length):
        px, py, qx, qy = jnp.broadcast_arrays(px, py, qx, qy)
        ux, uy = qx - px, qy - py
        inv = 1.0 / jnp.maximum(safe_norm(ux, uy), 1e-9)
        index = walls_along(m, px, py, ux * inv, uy * inv, length)  # [S..., K]
        ax, ay, bx, by = (v[index] for v in (m.wall_x1, m.wall_y1, m.wall_x2, m.wall_y2))
        valid = m.wall_valid[index]
    else:
        ax, ay, bx, by = (v[(None,) * px.ndim] for v in (m.wall_x1, m.wall_y1, m.wall_x2,
                                                          m.wall_y2))
        valid = m.wall_valid[(None,) * px.ndim]
    px, py, qx, qy = (v[..., None] for v in (px, py, qx, qy))

    def side(ox: Array, oy: Array, ux: Array, uy: Array, wx: Array, wy: Array) -> Array:
        return (ux - ox) * (wy - oy) - (uy - oy) * (wx - ox)

    d1, d2 = side(ax, ay, bx, by, px, py), side(ax, ay, bx, by, qx, qy)
    d3, d4 = side(px, py, qx, qy, ax, ay), side(px, py, qx, qy, bx, by)
    crosses = (d1 * d2 < 0.0) & (d3 * d4 < 0.0) & valid
    return ~jnp.any(crosses, axis=-1)


def body_gaps(state: EnvState, params: EnvParams, layout: Layout, robots: bool = True,
              humans: bool = True) -> Array:
    """``[R, B]`` body-to-body gaps (m, negative when overlapping); ``FAR`` for bodies that
    are not there and for the robot itself."""
    r = state.robots
    b = gather_bodies(state, params, robots=robots, humans=humans)
    gap = (safe_norm(b.x[None, :] - r.x[:, None], b.y[None, :] - r.y[:, None])
           - b.radius[None, :] - params.robots.radius[:, None])
    there = jnp.broadcast_to(b.in_world[None, :], gap.shape)
    if robots:
        there = there & ~jnp.eye(layout.max_agents, b.x.shape[0], dtype=bool)
    return jnp.where(there, gap, FAR)


def collided(prev: EnvState, state: EnvState, robots: bool, walls: bool, humans: bool,
             per_step: bool) -> Array:
    """``[R]`` bool: a collision of the chosen kinds began this step (``per_step``: is going
    on)."""
    out = jnp.zeros(state.robots.x.shape, bool)
    for chosen, now, before in ((robots, state.touching_robot, prev.touching_robot),
                                (walls, state.touching_wall, prev.touching_wall),
                                (humans, state.touching_human, prev.touching_human)):
        if chosen:
            out = out | (now if per_step else now & ~before)
    return out
