"""The local planner behind the GO action: pure pursuit along the route plus arc sampling.

Per robot and step:
  1. the carrot is the point ``carrot_distance`` (1.5 m, SocialGym's value) further along the route
     than the robot's progress (its projection on the route, never moving backwards);
  2. if the carrot's bearing exceeds ``turn_in_place_angle`` (30 degrees) the robot halts (below
     ``halt_speed``) and then turns toward it with time-optimal yaw control (Ackermann robots
     cannot, and keep to arcs);
  3. otherwise ``num_arcs`` constant-curvature arcs with curvature in
     ``[-max_curvature, max_curvature]`` (SocialGym: 41 arcs in [-2, 2] 1/m; Ackermann robots are
     limited to ``1 / min_turn_radius``) are sampled at ``arc_lengths`` (m, each arc cut at a
     quarter turn). An arc is free up to the last sample whose disc (own radius +
     ``obstacle_margin``) clears every wall and every other body (robots in the world,
     pedestrians) where the body will be when the robot gets to the sample at full speed (its
     velocity extrapolated, times ``prediction``); a sample that is
     farther from a body than the robot is now is never blocked by it, so a robot that is
     already close can move away. The arc whose free end is closest to the carrot wins, with
     ``clearance_weight`` per metre of wall clearance (up to 1 m) as a tie-breaker; a robot
     meeting a body (one blocks any of its arcs) pays up to ``pass_bias`` for left arcs, so two
     robots meeting both keep right and pass. Walls come from the map's per-cell lists
     (``MapArrays.cell_walls``), which hold every wall within reach of the cell: ``make`` sizes
     them for the longest arc plus the inflated radius;
  4. the speed is the largest from which the robot can stop within the arc's free length:
     ``min(max_speed, sqrt(2 max_decel (free - stop_margin)))``, and the yaw rate is the speed the
     robot reaches this step x curvature (steering ``atan(wheelbase x curvature)`` for Ackermann).
Cost: ``R * S * (Kw + B)`` distance evaluations per step, with ``S`` the distinct samples of all
arcs (at most ``num_arcs * len(arc_lengths)``: 40 of 44 by default, as the sharpest arcs' last two
samples coincide at the quarter turn), ``Kw`` the longest per-cell wall list and ``B`` the other
robots and pedestrians. On XLA's CPU backend each test is a chain of ``[R, S]`` operations over
the walls and the bodies, which it fuses into one pass (a reduction over an ``[R, Kw or B, S]``
axis ran element by element, recomputing the samples for every wall or body: six times slower).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from flax import struct
from jax import Array

from sgjax.dynamics.limits import ACKERMANN, RobotParams
from sgjax.maps.arrays import MapArrays
from sgjax.maps.sampling import Route

_TINY = 1e-12  # m^2: as sgjax.kernels.geometry's floor of squared segment lengths


@dataclasses.dataclass(frozen=True)
class PlannerConfig:
    """Static planner settings (they fix array shapes, so changing them recompiles)."""

    num_arcs: int = 11
    arc_lengths: tuple[float, ...] = (0.3, 0.6, 1.0, 1.5)
    max_curvature: float = 2.0  # 1/m

    def arcs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Arc curvatures ``[K]`` (1/m), and sample arc lengths and robot-frame points
        ``[K, M]`` (m); every arc is cut at a quarter turn."""
        curv = np.linspace(-self.max_curvature, self.max_curvature, self.num_arcs)
        quarter = np.pi / (2.0 * np.maximum(np.abs(curv), 1e-9))
        s = np.minimum(np.asarray(self.arc_lengths)[None, :], quarter[:, None])
        theta = curv[:, None] * s
        local_x = s * np.sinc(theta / np.pi)
        local_y = s * 0.5 * theta * np.sinc(theta / (2 * np.pi)) ** 2
        return curv, s, local_x, local_y

    def __post_init__(self) -> None:
        if self.num_arcs < 3 or self.num_arcs % 2 == 0:
            raise ValueError(f"planner num_arcs must be odd and >= 3, got {self.num_arcs}")
        lengths = self.arc_lengths
        if not lengths or any(b <= a for a, b in zip(lengths, lengths[1:], strict=False)) or (
            lengths[0] <= 0
        ):
            raise ValueError(f"planner arc_lengths must be positive and increasing, got {lengths}")
        if not self.max_curvature > 0:
            raise ValueError(f"planner max_curvature must be positive, got {self.max_curvature}")


@struct.dataclass
class PlannerParams:
    """Float planner settings (a pytree: sweepable).

    The map's per-cell wall lists are sized by ``make`` for the longest arc plus the largest
    robot radius plus ``obstacle_margin`` plus 0.2 m: raising ``obstacle_margin`` by more than
    0.2 m afterwards can hide walls from the planner (never from the contacts).
    """

    carrot_distance: Array | float = 1.5  # m
    turn_in_place_angle: Array | float = jnp.pi / 6  # rad
    obstacle_margin: Array | float = 0.1  # m
    stop_margin: Array | float = 0.05  # m
    halt_speed: Array | float = 0.1  # m/s: turn in place only below this speed
    clearance_weight: Array | float = 0.5  # cost per m of clearance
    prediction: Array | float = 1.0  # bodies extrapolated this x arrival time ahead (0: static)
    pass_bias: Array | float = 0.3  # cost (m) of the sharpest left arc when meeting a body


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
    dist_sq = jnp.where(eligible, dist_sq, jnp.inf)
    # Reductions over the few segments as chains of [R] operations: argmin is slow on the CPU,
    # and so are float reductions over a short axis (a library kernel, not XLA's loops).
    segments = range(dist_sq.shape[1])
    lowest = functools.reduce(jnp.minimum, (dist_sq[:, j] for j in segments))
    s_best = functools.reduce(jnp.maximum, (
        jnp.where((dist_sq[:, j] <= lowest) & eligible[:, j], s[:, j], -jnp.inf)
        for j in segments))
    return jnp.maximum(progress, s_best)


def point_along_route(route: Route, s: Array) -> tuple[Array, Array]:
    """World point at arc length ``s`` ``[R]`` (clipped to the route's ends)."""
    s = jnp.clip(s, 0.0, route.total_length)
    s0, s1 = route.cum_length[:, :-1], route.cum_length[:, 1:]
    # The segment holding s: s0 <= s < s1 (half-open, so exactly one), or the last segment of
    # positive length when s is the route's end. Padding segments have zero length.
    at_end = s1 >= route.total_length[:, None]
    on = (s0 <= s[:, None]) & ((s[:, None] < s1) | at_end) & (s1 > s0)
    frac = jnp.clip((s[:, None] - s0) / jnp.maximum(s1 - s0, 1e-9), 0.0, 1.0)
    px = route.x[:, :-1] + frac * (route.x[:, 1:] - route.x[:, :-1])
    py = route.y[:, :-1] + frac * (route.y[:, 1:] - route.y[:, :-1])
    return jnp.sum(jnp.where(on, px, 0.0), axis=1), jnp.sum(jnp.where(on, py, 0.0), axis=1)


def plan(
    config: PlannerConfig,
    pp: PlannerParams,
    robots: RobotParams,
    m: MapArrays,
    x: Array,
    y: Array,
    heading: Array,
    v_forward: Array,
    dt: Array,
    in_world: Array,
    carrot_x: Array,
    carrot_y: Array,
    velocity: tuple[Array, Array] | None = None,
    bodies: tuple[Array, Array, Array, Array, Array, Array] | None = None,
    speed_limit: Array | None = None,
) -> tuple[Array, Array]:
    """GO commands ``(forward m/s, turn)`` ``[R]`` toward the carrots, avoiding walls, robots and
    other bodies; ``speed_limit [R]`` (m/s, optional) caps each robot's speed below its own
    (the yaw rate follows, so the driven arc is the one checked).

    ``v_forward [R]`` is each robot's current forward speed (m/s) and ``dt`` the step (s).

    ``turn`` is a yaw rate (rad/s), or a steering angle (rad) for Ackermann robots.
    ``in_world [R]`` masks which robots are obstacles and ``velocity = (vx, vy)``, ``[R]`` each
    (m/s, world frame; default at rest), is how they move. ``bodies`` adds discs
    ``(x, y, vx, vy, radius, present)``, each ``[B]`` (pedestrians).
    """
    ackermann = robots.model == ACKERMANN
    cos_h, sin_h = jnp.cos(heading), jnp.sin(heading)
    local_x, local_y = _robot_frame(cos_h, sin_h, carrot_x - x, carrot_y - y)
    bearing = jnp.arctan2(local_y, local_x)

    # Arc samples: constants in the robot frame, flattened to the S distinct samples of all arcs
    # (an arc cut at a quarter turn repeats its last sample: that one is tested once) so that
    # the innermost axis is long (XLA's CPU backend vectorises the innermost axis), placed in
    # the world [R, S]. The wall and body tests are chains of [R, S] operations over the walls
    # and bodies: XLA fuses each into one pass, where a reduction over a [R, walls or bodies, S]
    # tensor ran as an elemental reduce that recomputed the samples for every wall or body.
    table = _arc_table(config)
    px = x[:, None] + cos_h[:, None] * table.ax - sin_h[:, None] * table.ay
    py = y[:, None] + sin_h[:, None] * table.ax + cos_h[:, None] * table.ay
    arrival = pp.prediction * jnp.asarray(table.s)[None, :] / robots.max_speed[:, None]  # [R, S]
    inflate = (robots.radius + pp.obstacle_margin)[:, None]

    wall_clearance = _wall_clearance(m, x, y, px, py) - inflate  # [R, S]
    body_blocked = _body_blocked(x, y, px, py, arrival, inflate, robots.radius, in_world,
                                 velocity, bodies)  # [R, S]
    # Keep right: a robot with a body on any of its arcs pays ``pass_bias`` per unit of left
    # curvature (as a fraction of the largest), so two robots meeting pass on the same side.
    meeting = jnp.any(body_blocked, axis=1)
    blocked = (wall_clearance < 0.0) | body_blocked
    best_curv, best_free = _choose_arc(config, pp, robots, table, blocked, wall_clearance,
                                       meeting, local_x, local_y, ackermann)

    stop_speed = jnp.sqrt(2.0 * robots.max_decel * jnp.maximum(best_free - pp.stop_margin, 0.0))
    speed = jnp.minimum(robots.max_speed, stop_speed)
    if speed_limit is not None:
        speed = jnp.minimum(speed, speed_limit)
    # Yaw rate for the speed the robot will actually reach this step (acceleration-limited), so
    # the driven curvature is the one that was checked.
    reached = v_forward + jnp.clip(speed - v_forward, -robots.max_decel * dt, robots.max_accel * dt)
    arc_turn = jnp.where(ackermann, jnp.arctan(robots.wheelbase * best_curv), reached * best_curv)

    # Turn in place (time-optimal: the fastest yaw rate that can still stop at the bearing),
    # after halting first, as SocialGym's TurnInPlace does: rotating while braking from speed
    # would swing the robot along an unchecked arc.
    turn_rate = _turn_in_place_rate(robots, bearing)
    # While meeting a body a robot may drive on arcs up to a right angle off the carrot (it is
    # passing); otherwise it turns in place beyond ``turn_in_place_angle``.
    limit = jnp.where(meeting, jnp.maximum(pp.turn_in_place_angle, jnp.pi / 2),
                      pp.turn_in_place_angle)
    turn_in_place = ~ackermann & (jnp.abs(bearing) > limit)
    # Blocked ahead on every arc: rotate toward the carrot rather than wait forever, or, when
    # bodies block it, to the right (keep right), up to a right angle off the carrot.
    stuck = ~ackermann & (best_free <= 0.0)
    right_limit = bearing < jnp.pi / 2 - 0.05
    give_way = stuck & meeting & right_limit
    turn_rate = jnp.where(give_way, -robots.max_omega * 0.5, turn_rate)
    rotate = turn_in_place | stuck
    halted = jnp.abs(v_forward) <= pp.halt_speed
    forward = jnp.where(rotate, 0.0, speed)
    turn = jnp.where(rotate, jnp.where(halted, turn_rate, 0.0), arc_turn)
    return forward, turn


class _ArcTable(NamedTuple):
    """The distinct samples of :meth:`PlannerConfig.arcs` as float32 constants: arc lengths
    ``s`` and robot-frame points ``ax``, ``ay`` ``[S]`` (m), and ``index [K, M]``, the distinct
    sample of each arc's each sample (an arc cut at a quarter turn repeats its end)."""

    s: np.ndarray
    ax: np.ndarray
    ay: np.ndarray
    index: np.ndarray


def _arc_table(config: PlannerConfig) -> _ArcTable:
    """The sample table of ``config``'s arcs, repeats removed (see :class:`_ArcTable`)."""
    _, s_km, ax_km, ay_km = config.arcs()
    index = np.zeros(s_km.shape, np.int32)
    s, ax, ay = [], [], []
    for j, k in np.ndindex(*s_km.shape[::-1]):  # sample-major: [R, K] slices per sample
        if j and s_km[k, j] == s_km[k, j - 1]:  # the same point as the sample before
            index[k, j] = index[k, j - 1]
            continue
        index[k, j] = len(s)
        s.append(s_km[k, j])
        ax.append(ax_km[k, j])
        ay.append(ay_km[k, j])
    f32 = np.float32
    return _ArcTable(np.asarray(s, f32), np.asarray(ax, f32), np.asarray(ay, f32), index)


def _wall_clearance(m: MapArrays, x: Array, y: Array, px: Array, py: Array) -> Array:
    """Distance (m) ``[R, S]`` from each robot's samples ``(px, py) [R, S]`` to the nearest
    wall listed for the robot's grid cell (``inf`` if none). The walls' vectors are computed
    once per robot and the minimum over the ``Kw`` listed walls is a chain of ``[R, S]``
    minima (one fused pass, no ``[R, Kw, S]`` tensor), with the arithmetic of
    :func:`sgjax.kernels.geometry.point_segment_distance_sq`."""
    near = m.cell_walls[m.cell_of(x, y)]  # [R, Kw]
    ax, ay, bx, by = (a[near] for a in (m.wall_x1, m.wall_y1, m.wall_x2, m.wall_y2))
    ex, ey = bx - ax, by - ay
    inv_length_sq = 1.0 / jnp.maximum(ex * ex + ey * ey, _TINY)
    walls = (ax, ay, ex, ey, inv_length_sq, m.wall_valid[near])
    d_sq = jnp.full(px.shape, jnp.inf)
    for k in range(near.shape[1]):
        ax_k, ay_k, ex_k, ey_k, inv_k, valid_k = (a[:, k, None] for a in walls)
        qx, qy = px - ax_k, py - ay_k
        t = jnp.clip((qx * ex_k + qy * ey_k) * inv_k, 0.0, 1.0)
        ox, oy = qx - t * ex_k, qy - t * ey_k
        d_sq = jnp.minimum(d_sq, jnp.where(valid_k, ox * ox + oy * oy, jnp.inf))
    return jnp.sqrt(d_sq)


def _body_blocked(
    x: Array, y: Array, px: Array, py: Array, arrival: Array, inflate: Array, radius: Array,
    in_world: Array, velocity: tuple[Array, Array] | None,
    bodies: tuple[Array, Array, Array, Array, Array, Array] | None,
) -> Array:
    """``[R, S]`` bool: whether another robot in the world, or a present body, blocks each
    sample ``(px, py) [R, S]`` (m): the sample comes within reach (``inflate [R, 1]`` plus the
    body's radius, m) of where the body will be at the robot's ``arrival [R, S]`` (s), and
    nearer to it than the robot is now. The per-pair limit (``-inf`` for pairs that are not
    obstacles) is computed at ``[R, B]``; the test is a chain of ``[R, S]`` ors over the ``B``
    bodies (one fused pass, no ``[R, B, S]`` tensor or reduction)."""
    num_robots = x.shape[0]
    other = in_world[None, :] & ~jnp.eye(num_robots, dtype=bool)  # [R, R]
    body_x, body_y, body_r = x, y, radius
    body_vx, body_vy = (jnp.zeros(num_robots, jnp.float32),) * 2 if velocity is None else velocity
    if bodies is not None:
        bx, by, bvx, bvy, br, bthere = bodies
        other = jnp.concatenate(
            [other, jnp.broadcast_to(bthere[None, :], (num_robots, bthere.shape[0]))], axis=1)
        body_x, body_y = jnp.concatenate([x, bx]), jnp.concatenate([y, by])
        body_vx, body_vy = jnp.concatenate([body_vx, bvx]), jnp.concatenate([body_vy, bvy])
        body_r = jnp.concatenate([radius, jnp.broadcast_to(br, bx.shape)])
    reach_sq = jnp.square(inflate + body_r[None, :])  # [R, B]
    now_sq = jnp.square(x[:, None] - body_x[None, :]) + jnp.square(y[:, None] - body_y[None, :])
    limit = jnp.where(other, jnp.minimum(reach_sq, now_sq), -jnp.inf)  # never below -inf
    blocked = jnp.zeros(px.shape, bool)
    for b in range(body_x.shape[0]):
        gap_x = px - body_x[b] - body_vx[b] * arrival
        gap_y = py - body_y[b] - body_vy[b] * arrival
        blocked = blocked | (jnp.square(gap_x) + jnp.square(gap_y) < limit[:, b, None])
    return blocked


def _choose_arc(
    config: PlannerConfig, pp: PlannerParams, robots: RobotParams, table: _ArcTable,
    blocked: Array, wall_clearance: Array, meeting: Array, local_x: Array, local_y: Array,
    ackermann: Array,
) -> tuple[Array, Array]:
    """The best arc's curvature (1/m) and free length (m), ``[R]`` each: each arc's samples are
    walked in order (``blocked`` and ``wall_clearance`` (m) are ``[R, S]``), and the arc whose
    free end is closest to the carrot ``(local_x, local_y) [R]`` (robot frame, m), less
    ``clearance_weight`` per metre of clearance along the free part (capped at 1 m), plus
    ``pass_bias`` for left arcs while ``meeting [R]``, wins; the first of equal costs wins.
    The costs are computed for all ``K`` arcs at once (``[R, K]``), so equal arcs tie exactly."""
    curv_k, s_km, ax_km, ay_km = (jnp.asarray(a, jnp.float32) for a in config.arcs())
    num_robots, (num_arcs, num_samples) = local_x.shape[0], s_km.shape
    # Ackermann robots may only use arcs within their turning limit.
    allowed = ~ackermann[:, None] | (
        jnp.abs(curv_k)[None, :] <= 1.0 / robots.min_turn_radius[:, None])
    # Walk each arc's samples in order ([R, K] slices: no argmax, gathers or short reductions).
    still_free = allowed
    free_len = jnp.zeros((num_robots, num_arcs), jnp.float32)
    end_x = jnp.zeros_like(free_len)
    end_y = jnp.zeros_like(free_len)
    free_clear = jnp.full(free_len.shape, 1.0)  # wall clearance along the free part, capped 1 m
    for k in range(num_samples):
        still_free = still_free & ~_columns(blocked, table.index[:, k])
        free_len = jnp.where(still_free, s_km[:, k], free_len)
        end_x = jnp.where(still_free, ax_km[:, k], end_x)
        end_y = jnp.where(still_free, ay_km[:, k], end_y)
        free_clear = jnp.where(
            still_free, jnp.minimum(free_clear, _columns(wall_clearance, table.index[:, k])),
            free_clear)
    free_clear = jnp.where(free_len > 0.0, free_clear, 0.0)
    to_carrot = jnp.sqrt(
        jnp.square(end_x - local_x[:, None]) + jnp.square(end_y - local_y[:, None]))
    left = jnp.maximum(curv_k, 0.0) / config.max_curvature  # [K] in [0, 1]
    side_cost = jnp.where(meeting[:, None], pp.pass_bias * left[None, :], 0.0)
    cost = jnp.where(allowed, to_carrot - pp.clearance_weight * free_clear + side_cost, jnp.inf)
    lowest = jnp.min(cost, axis=1, keepdims=True)
    arc_index = jnp.arange(num_arcs)
    best = jnp.min(jnp.where(cost <= lowest, arc_index, num_arcs), axis=1)  # first minimum
    is_best = arc_index[None, :] == best[:, None]
    best_curv = jnp.sum(jnp.where(is_best, curv_k[None, :], 0.0), axis=1)
    best_free = jnp.sum(jnp.where(is_best, free_len, 0.0), axis=1)
    return best_curv, best_free


def _columns(a: Array, index: np.ndarray) -> Array:
    """``a[:, index]`` for a static ``index``, as a concatenation of contiguous slices (XLA's
    CPU backend runs a gather element by element)."""
    runs = np.split(index, np.flatnonzero(np.diff(index) != 1) + 1)
    parts = [a[:, run[0]:run[-1] + 1] for run in runs]
    return parts[0] if len(parts) == 1 else jnp.concatenate(parts, axis=1)


def approach(
    pp: PlannerParams,
    robots: RobotParams,
    x: Array,
    y: Array,
    heading: Array,
    v_forward: Array,
    dt: Array,
    target_x: Array,
    target_y: Array,
) -> tuple[Array, Array]:
    """Commands ``(forward m/s, turn)`` ``[R]`` that drive each robot straight onto a nearby
    target point, with no obstacle checks (bumpers and contacts still apply): the pure-pursuit
    arc through the target (curvature ``2 y / d^2`` in the robot frame), no faster than the robot
    can stop at the target (``sqrt(2 max_decel d)``); beyond ``turn_in_place_angle`` of bearing
    it halts and turns in place, as :func:`plan` does (Ackermann robots keep to the arc), at the
    time-optimal rate for the chord ``2 sin(bearing / 2)``, a lower bound of the bearing (so it
    never overshoots). ``turn`` is a yaw rate (rad/s), or a steering angle (rad)
    for Ackermann robots. The cheap way to settle an arrived robot on its goal when :func:`plan`
    is not run (continuous actions)."""
    ackermann = robots.model == ACKERMANN
    local_x, local_y = _robot_frame(jnp.cos(heading), jnp.sin(heading), target_x - x,
                                    target_y - y)
    dist_sq = jnp.maximum(jnp.square(local_x) + jnp.square(local_y), 1e-12)
    dist = jnp.sqrt(dist_sq)
    curvature = 2.0 * local_y / dist_sq
    curvature = jnp.where(ackermann, jnp.clip(curvature, -1.0 / robots.min_turn_radius,
                                              1.0 / robots.min_turn_radius), curvature)
    speed = jnp.minimum(robots.max_speed, jnp.sqrt(2.0 * robots.max_decel * dist))  # dist > 0
    reached = v_forward + jnp.clip(speed - v_forward, -robots.max_decel * dt, robots.max_accel * dt)
    arc_turn = jnp.where(ackermann, jnp.arctan(robots.wheelbase * curvature),
                         reached * curvature)
    # 2 sin(|bearing| / 2); floored so that its gradient stays finite when facing the target
    # (a NaN there would leak through the caller's jnp.where into every gradient).
    chord = jnp.sqrt(jnp.maximum(2.0 - 2.0 * local_x / dist, 1e-12))
    turn_rate = _turn_in_place_rate(robots, jnp.sign(local_y) * chord)
    rotate = ~ackermann & (local_x < jnp.cos(pp.turn_in_place_angle) * dist)
    halted = jnp.abs(v_forward) <= pp.halt_speed
    forward = jnp.where(rotate, 0.0, speed)
    turn = jnp.where(rotate, jnp.where(halted, turn_rate, 0.0), arc_turn)
    return forward, turn


def _robot_frame(cos_h: Array, sin_h: Array, dx: Array, dy: Array) -> tuple[Array, Array]:
    """World offsets ``(dx, dy)`` (m) in the frame of robots heading ``(cos_h, sin_h)``."""
    return cos_h * dx + sin_h * dy, -sin_h * dx + cos_h * dy


def _turn_in_place_rate(robots: RobotParams, bearing: Array) -> Array:
    """Time-optimal yaw rate (rad/s) toward a ``bearing`` (rad): the fastest that can still
    stop at it under ``max_alpha``, capped at ``max_omega``."""
    return jnp.sign(bearing) * jnp.minimum(
        robots.max_omega, jnp.sqrt(2.0 * robots.max_alpha * jnp.abs(bearing)))


def carrot_point(pp: PlannerParams, route: Route, progress: Array) -> tuple[Array, Array]:
    """The pure-pursuit target ``carrot_distance`` ahead of each robot's progress."""
    return point_along_route(route, progress + pp.carrot_distance)
