"""The local planner behind the GO action: pure pursuit along the route plus arc sampling.

Per robot and step:
  1. the carrot is the point ``carrot_distance`` (1.5 m, SocialGym's value) further along the route
     than the robot's progress (its projection on the route, never moving backwards);
  2. if the carrot's bearing exceeds ``turn_in_place_angle`` (30 degrees) the robot stops and turns
     toward it with time-optimal yaw control (Ackermann robots cannot, and keep to arcs);
  3. otherwise ``num_arcs`` constant-curvature arcs with curvature in
     ``[-max_curvature, max_curvature]`` (SocialGym: 41 arcs in [-2, 2] 1/m; Ackermann robots are
     limited to ``1 / min_turn_radius``) are sampled at ``arc_lengths`` (m, each arc cut at a
     quarter turn). An arc is free up to the last sample whose disc (own radius +
     ``obstacle_margin``) clears every wall and every other robot's disc. The arc whose free end is
     closest to the carrot wins, with ``clearance_weight`` per metre of clearance (up to 1 m) as a
     tie-breaker;
  4. the speed is the largest from which the robot can stop within the arc's free length:
     ``min(max_speed, sqrt(2 max_decel (free - stop_margin)))``, and the yaw rate is speed x
     curvature (steering ``atan(wheelbase x curvature)`` for Ackermann robots).
Cost: ``R * num_arcs * len(arc_lengths) * (W + R)`` distance evaluations per step.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.dynamics.limits import ACKERMANN, RobotParams
from sgjax.geometry import point_segment_distance
from sgjax.maps.arrays import MapArrays
from sgjax.maps.sampling import Route


@dataclasses.dataclass(frozen=True)
class PlannerConfig:
    """Static planner settings (they fix array shapes, so changing them recompiles)."""

    num_arcs: int = 21
    arc_lengths: tuple[float, ...] = (0.25, 0.5, 0.8, 1.2, 1.6)

    def __post_init__(self) -> None:
        if self.num_arcs < 3 or self.num_arcs % 2 == 0:
            raise ValueError(f"planner num_arcs must be odd and >= 3, got {self.num_arcs}")
        lengths = self.arc_lengths
        if not lengths or any(b <= a for a, b in zip(lengths, lengths[1:], strict=False)) or (
            lengths[0] <= 0
        ):
            raise ValueError(f"planner arc_lengths must be positive and increasing, got {lengths}")


@struct.dataclass
class PlannerParams:
    """Float planner settings (a pytree: sweepable)."""

    carrot_distance: Array | float = 1.5  # m
    turn_in_place_angle: Array | float = jnp.pi / 6  # rad
    max_curvature: Array | float = 2.0  # 1/m
    obstacle_margin: Array | float = 0.1  # m
    stop_margin: Array | float = 0.05  # m
    clearance_weight: Array | float = 0.5  # cost per m of clearance


def route_progress(route: Route, x: Array, y: Array, progress: Array) -> Array:
    """New progress (m along the route) of robots at ``(x, y)``: the nearest projection on the
    route's segments at or ahead of the old progress minus 1 m, never less than the old progress."""
    ax, ay = route.x[:, :-1], route.y[:, :-1]
    bx, by = route.x[:, 1:], route.y[:, 1:]
    ex, ey = bx - ax, by - ay
    seg_len_sq = ex * ex + ey * ey
    t = ((x[:, None] - ax) * ex + (y[:, None] - ay) * ey) / jnp.maximum(seg_len_sq, 1e-9)
    t = jnp.clip(t, 0.0, 1.0)
    dist_sq = jnp.square(x[:, None] - ax - t * ex) + jnp.square(y[:, None] - ay - t * ey)
    s = route.cum_length[:, :-1] + t * jnp.sqrt(seg_len_sq)
    eligible = (seg_len_sq > 1e-9) & (s >= progress[:, None] - 1.0)
    best = jnp.argmin(jnp.where(eligible, dist_sq, jnp.inf), axis=1)
    s_best = jnp.take_along_axis(s, best[:, None], axis=1)[:, 0]
    return jnp.maximum(progress, jnp.where(jnp.any(eligible, axis=1), s_best, progress))


def point_along_route(route: Route, s: Array) -> tuple[Array, Array]:
    """World point at arc length ``s`` ``[R]`` (clipped to the route's ends)."""
    s = jnp.clip(s, 0.0, route.total_length)
    seg = jnp.sum(route.cum_length[:, 1:] < s[:, None], axis=1)
    seg = jnp.clip(seg, 0, route.x.shape[1] - 2)[:, None]
    s0 = jnp.take_along_axis(route.cum_length, seg, axis=1)[:, 0]
    s1 = jnp.take_along_axis(route.cum_length, seg + 1, axis=1)[:, 0]
    frac = jnp.clip((s - s0) / jnp.maximum(s1 - s0, 1e-9), 0.0, 1.0)
    x0, x1 = (jnp.take_along_axis(route.x, seg + k, axis=1)[:, 0] for k in (0, 1))
    y0, y1 = (jnp.take_along_axis(route.y, seg + k, axis=1)[:, 0] for k in (0, 1))
    return x0 + frac * (x1 - x0), y0 + frac * (y1 - y0)


def plan(
    config: PlannerConfig,
    pp: PlannerParams,
    robots: RobotParams,
    m: MapArrays,
    x: Array,
    y: Array,
    heading: Array,
    in_world: Array,
    carrot_x: Array,
    carrot_y: Array,
) -> tuple[Array, Array]:
    """GO commands ``(forward m/s, turn)`` ``[R]`` toward the carrots, avoiding walls and robots.

    ``turn`` is a yaw rate (rad/s), or a steering angle (rad) for Ackermann robots.
    ``in_world [R]`` masks which robots are obstacles.
    """
    ackermann = robots.model == ACKERMANN
    cos_h, sin_h = jnp.cos(heading), jnp.sin(heading)
    rel_x, rel_y = carrot_x - x, carrot_y - y
    local_x = cos_h * rel_x + sin_h * rel_y
    local_y = -sin_h * rel_x + cos_h * rel_y
    bearing = jnp.arctan2(local_y, local_x)

    # Arc samples in each robot's frame: [R, K, M].
    c_max = jnp.where(ackermann, jnp.minimum(pp.max_curvature, 1.0 / robots.min_turn_radius),
                      pp.max_curvature)
    unit = jnp.linspace(-1.0, 1.0, config.num_arcs)
    curv = c_max[:, None] * unit[None, :]  # [R, K]
    lengths = jnp.asarray(config.arc_lengths)
    quarter = jnp.pi / (2.0 * jnp.maximum(jnp.abs(curv), 1e-6))
    s = jnp.minimum(lengths[None, None, :], quarter[:, :, None])  # [R, K, M]
    theta = curv[:, :, None] * s
    ax_local = s * jnp.sinc(theta / jnp.pi)
    ay_local = s * 0.5 * theta * jnp.square(jnp.sinc(theta / (2.0 * jnp.pi)))
    ch, sh = cos_h[:, None, None], sin_h[:, None, None]
    px = x[:, None, None] + ch * ax_local - sh * ay_local
    py = y[:, None, None] + sh * ax_local + ch * ay_local

    # Clearance of every sample from walls and other robots: [R, K, M].
    inflate = (robots.radius + pp.obstacle_margin)[:, None, None]
    wall_d = point_segment_distance(
        px[..., None], py[..., None], m.wall_x1, m.wall_y1, m.wall_x2, m.wall_y2
    )
    wall_d = jnp.where(m.wall_valid, wall_d, jnp.inf)
    clearance = jnp.min(wall_d, axis=-1) - inflate
    num_robots = x.shape[0]
    other = in_world[None, :] & ~jnp.eye(num_robots, dtype=bool)  # [R, R]
    body_d = jnp.sqrt(
        jnp.square(px[..., None] - x[None, None, None, :])
        + jnp.square(py[..., None] - y[None, None, None, :])
    ) - robots.radius[None, None, None, :]
    body_d = jnp.where(other[:, None, None, :], body_d, jnp.inf)
    clearance = jnp.minimum(clearance, jnp.min(body_d, axis=-1) - inflate)

    blocked = clearance < 0.0
    first_blocked = jnp.argmax(blocked, axis=-1)  # [R, K]; 0 if none blocked
    any_blocked = jnp.any(blocked, axis=-1)
    num_samples = len(config.arc_lengths)
    free_index = jnp.where(any_blocked, first_blocked - 1, num_samples - 1)  # -1: nothing free
    safe_index = jnp.maximum(free_index, 0)[..., None]
    free_len = jnp.where(free_index >= 0, jnp.take_along_axis(s, safe_index, -1)[..., 0], 0.0)
    end_x = jnp.where(free_index >= 0, jnp.take_along_axis(ax_local, safe_index, -1)[..., 0], 0.0)
    end_y = jnp.where(free_index >= 0, jnp.take_along_axis(ay_local, safe_index, -1)[..., 0], 0.0)
    sample_index = jnp.arange(num_samples)
    free_clear = jnp.min(jnp.where(sample_index <= free_index[..., None], clearance, jnp.inf), -1)
    free_clear = jnp.where(free_index >= 0, jnp.minimum(free_clear, 1.0), 0.0)
    to_carrot = jnp.sqrt(jnp.square(end_x - local_x[:, None]) + jnp.square(end_y - local_y[:, None]))
    cost = to_carrot - pp.clearance_weight * free_clear
    best = jnp.argmin(cost, axis=1)[:, None]
    best_curv = jnp.take_along_axis(curv, best, 1)[:, 0]
    best_free = jnp.take_along_axis(free_len, best, 1)[:, 0]

    stop_speed = jnp.sqrt(2.0 * robots.max_decel * jnp.maximum(best_free - pp.stop_margin, 0.0))
    speed = jnp.minimum(robots.max_speed, stop_speed)
    arc_turn = jnp.where(ackermann, jnp.arctan(robots.wheelbase * best_curv), speed * best_curv)

    # Turn in place (time-optimal: the fastest yaw rate that can still stop at the bearing).
    turn_rate = jnp.sign(bearing) * jnp.minimum(
        robots.max_omega, jnp.sqrt(2.0 * robots.max_alpha * jnp.abs(bearing))
    )
    turn_in_place = ~ackermann & (jnp.abs(bearing) > pp.turn_in_place_angle)
    # Blocked ahead on every arc: rotate toward the carrot rather than wait forever.
    stuck = ~ackermann & (best_free <= 0.0)
    rotate = turn_in_place | stuck
    forward = jnp.where(rotate, 0.0, speed)
    turn = jnp.where(rotate, turn_rate, arc_turn)
    return forward, turn


def carrot_point(pp: PlannerParams, route: Route, progress: Array) -> tuple[Array, Array]:
    """The pure-pursuit target ``carrot_distance`` ahead of each robot's progress."""
    return point_along_route(route, progress + pp.carrot_distance)
