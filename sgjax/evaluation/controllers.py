"""Classical continuous-action controllers for the robots, as policies
(``policy(obs, key, state, params) -> actions [R, d]`` in [-1, 1]; jittable, vmappable).

``orca``: every robot takes the ORCA velocity (:mod:`sgjax.kernels.orca`; van den Berg et al. 2011)
toward its pure-pursuit carrot on its route, avoiding the other robots (reciprocally: they run
the same controller; parked robots are static), pedestrians (all of the avoidance: they may not
reciprocate) and the nearest walls (:func:`sgjax.kernels.orca.wall_lines`), then tracks that
velocity
under its own kinematics:

* omnidirectional robots command it directly (forward and lateral in the body frame) and turn
  toward it;
* differential-drive robots turn toward it at ``heading_gain`` (1/s) x the heading error and
  drive at its speed times the cosine of that error (zero when it points behind them);
* Ackermann robots steer for the yaw rate the differential-drive rule asks for at their speed.

The environment's integrator applies every robot's acceleration, turn-rate and steering limits,
so the kinodynamic limits hold whatever is commanded; a non-holonomic robot can lag the ORCA
velocity while it turns, which ORCA's guarantee does not cover (the contacts still stop it).
Constants and their sources: docs/baselines.md.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp
from jax import Array

from sgjax.dynamics.limits import ACKERMANN, OMNIDIRECTIONAL
from sgjax.dynamics.planner import carrot_point, point_along_route
from sgjax.humans.forces import (
    cap_speed,
    desired_force,
    exponential_wall_force,
    moussaid_interaction,
)
from sgjax.kernels.geometry import (
    point_segment_distance,
    point_segment_offset,
    safe_norm,
    wrap_angle,
)
from sgjax.kernels.orca import nearest_bodies, nearest_walls, orca_velocity, wall_lines

if TYPE_CHECKING:
    from sgjax.environment.env import SocialNavEnv
    from sgjax.types import EnvParams, EnvState


@dataclasses.dataclass(frozen=True)
class OrcaControllerSettings:
    """Constants of the ``orca`` controller (static: they shape or steer the program)."""

    time_horizon: float = 2.0  # s: bodies (robots are faster than pedestrians: a shorter look)
    obstacle_time_horizon: float = 1.0  # s: walls
    neighbors: int = 10  # nearest bodies considered
    walls: int = 4  # nearest walls considered
    heading_gain: float = 2.0  # 1/s: turn rate per radian of heading error
    arrive_time: float = 1.0  # s: slow down within this time of the goal
    pedestrian_share: float = 1.0  # avoidance a robot takes from a pedestrian
    # m added to every radius: a non-holonomic robot lags the velocity ORCA asks for while it
    # turns, which ORCA's guarantee does not cover (CrowdNav's "safety space" does the same).
    safety_margin: float = 0.1
    # rad the preferred velocity is turned clockwise: exactly opposed robots would otherwise
    # slow down nose to nose (ORCA's symmetric case); all keep right instead.
    keep_right: float = 0.1


def _require_continuous(env: SocialNavEnv, name: str) -> None:
    if env.config.action_mode != "continuous":
        raise ValueError(f"policy {name!r} commands velocities and needs action_mode "
                         f"'continuous'; this environment has {env.config.action_mode!r} "
                         "(make(..., action_mode='continuous'))")


def orca_controller(env: SocialNavEnv, settings: OrcaControllerSettings | None = None):
    """The ``orca`` baseline policy for ``env`` (continuous actions; see the module doc)."""
    _require_continuous(env, "orca")
    s = settings or OrcaControllerSettings()
    action_dim = env.config.action_dim

    def policy(obs: Array, key: Array, state: EnvState, params: EnvParams) -> Array:
        r, h, m, rp = state.robots, state.humans, params.map, params.robots
        num = r.x.shape[0]
        cx, cy = carrot_point(params.planner, state.route, state.progress)
        gx, gy = cx - r.x, cy - r.y
        to_carrot = safe_norm(gx, gy)
        speed = jnp.minimum(rp.max_speed, state.goal_distance / s.arrive_time)
        c, si = jnp.cos(s.keep_right), jnp.sin(s.keep_right)
        ux, uy = gx / jnp.maximum(to_carrot, 1e-9), gy / jnp.maximum(to_carrot, 1e-9)
        pref_x = (c * ux + si * uy) * speed
        pref_y = (-si * ux + c * uy) * speed
        velocity = r.body_velocity

        # Bodies: robots then pedestrians.
        bx = jnp.concatenate([r.x, h.x])
        by = jnp.concatenate([r.y, h.y])
        bvx = jnp.concatenate([velocity[:, 0], h.vx])
        bvy = jnp.concatenate([velocity[:, 1], h.vy])
        human_radius = jnp.broadcast_to(params.humans.radius, h.x.shape)
        bradius = jnp.concatenate([rp.radius, human_radius])
        share = jnp.concatenate([jnp.where(r.active, 0.5, 1.0),
                                 jnp.full(h.x.shape, s.pedestrian_share)])
        present = jnp.concatenate([r.in_world, h.active])
        pair = present[None, :] & ~jnp.eye(num, bx.shape[0], dtype=bool)
        near, near_valid = nearest_bodies(r.x, r.y, bx, by, pair, s.neighbors)
        wall_near, wall_valid = nearest_walls(r.x, r.y, m, s.walls)

        def one(i: Array) -> tuple[Array, Array]:
            idx, w = near[i], wall_near[i]
            walls = wall_lines(r.x[i], r.y[i], velocity[i, 0], velocity[i, 1],
                               rp.radius[i] + s.safety_margin,
                               m.wall_x1[w], m.wall_y1[w], m.wall_x2[w], m.wall_y2[w],
                               wall_valid[i], s.obstacle_time_horizon, params.dt)
            return orca_velocity(
                r.x[i], r.y[i], velocity[i, 0], velocity[i, 1], rp.radius[i] + s.safety_margin,
                pref_x[i], pref_y[i], rp.max_speed[i], bx[idx], by[idx], bvx[idx], bvy[idx],
                bradius[idx], share[idx], near_valid[i], s.time_horizon, params.dt,
                walls=walls)

        vx, vy = jax.vmap(one)(jnp.arange(num))
        return track_velocity(vx, vy, r.heading, r.kin.v_forward, rp, s.heading_gain,
                              action_dim)

    return policy


def track_velocity(vx: Array, vy: Array, heading: Array, v_forward: Array, rp,
                   heading_gain: float, action_dim: int) -> Array:
    """Normalised actions ``[R, action_dim]`` that track world velocities ``(vx, vy)`` (m/s)
    under each robot's kinematics (see the module doc). ``rp``: ``RobotParams``."""
    c, s = jnp.cos(heading), jnp.sin(heading)
    body_forward = c * vx + s * vy
    body_lateral = -s * vx + c * vy
    speed = safe_norm(vx, vy)
    moving = speed > 1e-3
    error = jnp.where(moving, wrap_angle(jnp.arctan2(vy, vx) - heading), 0.0)
    omni = rp.model == OMNIDIRECTIONAL
    ackermann = rp.model == ACKERMANN
    forward = jnp.where(omni, body_forward, jnp.maximum(speed * jnp.cos(error), 0.0))
    lateral = jnp.where(omni, body_lateral, 0.0)
    yaw_rate = jnp.clip(heading_gain * error, -rp.max_omega, rp.max_omega)
    # Ackermann: the steering angle that gives that yaw rate at the current (or commanded) speed.
    drive = jnp.maximum(jnp.maximum(jnp.abs(v_forward), forward), 0.1)
    steer = jnp.arctan(rp.wheelbase * yaw_rate / drive)
    turn = jnp.where(ackermann, steer, yaw_rate)
    turn_limit = jnp.where(ackermann, rp.max_steering, rp.max_omega)
    forward_scale = jnp.where(forward >= 0.0, rp.max_speed, rp.max_reverse_speed)
    a_forward = jnp.clip(forward / jnp.maximum(forward_scale, 1e-9), -1.0, 1.0)
    a_turn = jnp.clip(turn / jnp.maximum(turn_limit, 1e-9), -1.0, 1.0)
    if action_dim == 3:
        a_lateral = jnp.clip(lateral / jnp.maximum(rp.max_speed, 1e-9), -1.0, 1.0)
        return jnp.stack([a_forward, a_lateral, a_turn], axis=-1)
    return jnp.stack([a_forward, a_turn], axis=-1)


@dataclasses.dataclass(frozen=True)
class DwaSettings:
    """Constants of the ``dwa`` controller (Fox, Burgard and Thrun 1997, "The dynamic window
    approach to collision avoidance")."""

    speeds: int = 7  # forward speeds sampled across the window
    turns: int = 11  # turn rates sampled across the window
    window: float = 0.25  # s: the window is what the accelerations reach in this time
    horizon: float = 1.5  # s: each sample is rolled out as a circular arc this long
    points: int = 8  # points checked along each arc
    heading_weight: float = 0.8  # on the alignment of the arc's end with the carrot
    clearance_weight: float = 0.2  # on the arc's smallest clearance, capped at clearance_cap
    speed_weight: float = 0.1  # on the forward speed, as a share of the top speed
    # on the progress toward the way on (the distance the arc's end gains, as a share of the
    # farthest an arc reaches): without it a robot whose goal lies near a wall stops short,
    # as standing still keeps the clearance term whole (measured: 1.3 m short, for ever)
    progress_weight: float = 0.4
    clearance_cap: float = 1.0  # m
    margin: float = 0.05  # m added to the robot's radius
    pass_angle: float = 0.6  # rad: how far right of the way on a blocked robot aims


@dataclasses.dataclass(frozen=True)
class DwaArcs:
    """The sampled commands of every robot and the circular arcs they drive: ``v [R, V, 1]``
    m/s and ``w [R, 1, W]`` rad/s (broadcast to ``[R, V, W]``), the points ``x, y [R, V, W, T]``
    (m, world) reached at times ``t [T]`` (s), and the heading there ``theta [R, V, W, T]``."""

    v: Array
    w: Array
    t: Array
    x: Array
    y: Array
    theta: Array


def _dwa_arcs(state: EnvState, params: EnvParams, s: DwaSettings) -> DwaArcs:
    """Forward speeds and turn rates reachable within ``s.window`` under each robot's limits,
    each rolled out as an arc for ``s.horizon``."""
    r, rp = state.robots, params.robots
    v0, w0 = r.kin.v_forward, r.kin.omega
    frac_v = jnp.linspace(-1.0, 1.0, s.speeds)
    frac_w = jnp.linspace(-1.0, 1.0, s.turns)
    v = jnp.clip(v0[:, None] + frac_v[None, :] * rp.max_accel[:, None] * s.window, 0.0,
                 rp.max_speed[:, None])  # [R, V]
    w = jnp.clip(w0[:, None] + frac_w[None, :] * rp.max_alpha[:, None] * s.window,
                 -rp.max_omega[:, None], rp.max_omega[:, None])  # [R, W]
    vv, ww = v[:, :, None], w[:, None, :]  # [R, V, W]
    t = jnp.linspace(s.horizon / s.points, s.horizon, s.points)  # [T]
    theta = r.heading[:, None, None, None] + ww[..., None] * t  # [R, V, W, T]
    straight = jnp.abs(ww[..., None]) < 1e-3
    safe_w = jnp.where(straight, 1.0, ww[..., None])
    dx = jnp.where(straight, vv[..., None] * t * jnp.cos(r.heading)[:, None, None, None],
                   vv[..., None] / safe_w * (jnp.sin(theta)
                                             - jnp.sin(r.heading)[:, None, None, None]))
    dy = jnp.where(straight, vv[..., None] * t * jnp.sin(r.heading)[:, None, None, None],
                   -vv[..., None] / safe_w * (jnp.cos(theta)
                                              - jnp.cos(r.heading)[:, None, None, None]))
    return DwaArcs(v=vv, w=ww, t=t, x=r.x[:, None, None, None] + dx,
                   y=r.y[:, None, None, None] + dy, theta=theta)


@dataclasses.dataclass(frozen=True)
class DwaBodies:
    """The bodies a robot avoids, robots first: ``x, y [T, B]`` (m) where their present
    velocities take them at each arc time, ``radius [B]`` (m), ``other [R, B]`` (bool: in the
    world, not the robot itself)."""

    x: Array
    y: Array
    radius: Array
    other: Array


def _dwa_bodies(state: EnvState, params: EnvParams, t: Array) -> DwaBodies:
    r, h, rp = state.robots, state.humans, params.robots
    velocity = r.body_velocity
    bx = jnp.concatenate([r.x, h.x])[None, :] + t[:, None] * jnp.concatenate(
        [velocity[:, 0], h.vx])[None, :]  # [T, B]
    by = jnp.concatenate([r.y, h.y])[None, :] + t[:, None] * jnp.concatenate(
        [velocity[:, 1], h.vy])[None, :]
    bradius = jnp.concatenate([rp.radius, jnp.broadcast_to(params.humans.radius, h.x.shape)])
    present = jnp.concatenate([r.in_world, h.active])
    other = present[None, :] & ~jnp.eye(r.x.shape[0], bx.shape[1], dtype=bool)  # [R, B]
    return DwaBodies(x=bx, y=by, radius=bradius, other=other)


def _dwa_clearance(arcs: DwaArcs, bodies: DwaBodies, params: EnvParams, s: DwaSettings
                   ) -> Array:
    """``[R, V, W]`` m: each arc's smallest clearance to the walls (nearest point of each) and
    to the bodies where they will be at each point's time."""
    m, rp = params.map, params.robots
    px, py = arcs.x, arcs.y
    radius = (rp.radius + s.margin)[:, None, None, None]
    wall = point_segment_distance(px[..., None], py[..., None], m.wall_x1, m.wall_y1,
                                  m.wall_x2, m.wall_y2)
    wall = jnp.min(jnp.where(m.wall_valid, wall, jnp.inf), axis=-1) - radius
    gap = ((safe_norm(px[..., None] - bodies.x, py[..., None] - bodies.y) - bodies.radius)
           - radius[..., None])
    gap = jnp.min(jnp.where(bodies.other[:, None, None, None, :], gap, jnp.inf), axis=-1)
    return jnp.min(jnp.minimum(wall, gap), axis=-1)


def _dwa_way_on(state: EnvState, params: EnvParams, bodies: DwaBodies, s: DwaSettings
                ) -> tuple[Array, Array]:
    """``[R]`` m, world: the point each robot heads for: a point of its route beyond the
    arcs' reach, turned ``pass_angle`` clockwise when a body is in the way."""
    r, rp = state.robots, params.robots
    ahead = state.progress + s.horizon * rp.max_speed + 1.0
    gx, gy = point_along_route(state.route, ahead)
    # Keep right: with a body in the way (within clearance_cap of the path straight ahead,
    # in front), aim pass_angle clockwise of the way on; a symmetric head-on meeting
    # otherwise ends nose to nose (DWA treats bodies as obstacles, not as agents).
    hx, hy = jnp.cos(r.heading), jnp.sin(r.heading)
    rel_x, rel_y = bodies.x[0][None, :] - r.x[:, None], bodies.y[0][None, :] - r.y[:, None]
    along = rel_x * hx[:, None] + rel_y * hy[:, None]
    across = jnp.abs(-rel_x * hy[:, None] + rel_y * hx[:, None])
    in_way = bodies.other & (along > 0.0) & (across < (rp.radius + s.margin)[:, None]
                                             + bodies.radius + s.clearance_cap * 0.5) & (
        along < s.horizon * rp.max_speed[:, None] + s.clearance_cap)
    blocked = jnp.any(in_way, axis=1)
    wx_, wy_ = gx - r.x, gy - r.y
    turn_by = jnp.where(blocked, -s.pass_angle, 0.0)
    c, si = jnp.cos(turn_by), jnp.sin(turn_by)
    return r.x + c * wx_ - si * wy_, r.y + si * wx_ + c * wy_


def _dwa_score(arcs: DwaArcs, clearance: Array, gx: Array, gy: Array, state: EnvState,
               params: EnvParams, s: DwaSettings) -> Array:
    """``[R, V, W]``: the weighted sum of heading, clearance, speed and progress of each arc;
    -inf for arcs on which the robot could not stop before the nearest obstacle."""
    r, rp = state.robots, params.robots
    vv = arcs.v
    stop_distance = vv * vv / (2.0 * rp.max_decel[:, None, None])
    admissible = clearance > stop_distance
    # Heading: alignment of the arc's end direction with the way on, seen from where the robot
    # is (an arc that runs past the point still points the right way).
    ex, ey = (gx - r.x)[:, None, None], (gy - r.y)[:, None, None]
    end = arcs.theta[..., -1]
    to_way = safe_norm(ex, ey)  # m from the robot to the way on
    align = (jnp.cos(end) * ex + jnp.sin(end) * ey) / jnp.maximum(to_way, 1e-9)
    reach = s.horizon * rp.max_speed[:, None, None]
    gained = to_way - safe_norm(gx[:, None, None] - arcs.x[..., -1],
                                gy[:, None, None] - arcs.y[..., -1])
    score = (s.heading_weight * (align + 1.0) / 2.0
             + s.clearance_weight * jnp.minimum(clearance, s.clearance_cap) / s.clearance_cap
             + s.speed_weight * vv / rp.max_speed[:, None, None]
             + s.progress_weight * gained / reach)
    return jnp.where(admissible, score, -jnp.inf)


def dwa_controller(env: SocialNavEnv, settings: DwaSettings | None = None):
    """The ``dwa`` baseline policy for ``env`` (continuous actions). For each robot: sample
    forward speeds and turn rates reachable within ``window`` s under its acceleration limits,
    roll each out as an arc for ``horizon`` s against the walls, the other robots and the
    pedestrians (where their present velocities take them), keep the admissible ones (it can
    stop, at its
    deceleration limit, before the nearest obstacle on the arc), and take the best weighted
    sum of heading (alignment of the arc's end heading with the way on, a route point beyond
    the arc's reach seen from the robot; 1 = straight at it), clearance, speed and progress
    toward that point (ties go to the most clockwise turn: robots keep right). When nothing is
    admissible, brake.
    Ackermann robots steer for the chosen yaw rate; omnidirectional robots drive like
    differential-drive ones."""
    _require_continuous(env, "dwa")
    s = settings or DwaSettings()
    action_dim = env.config.action_dim

    def policy(obs: Array, key: Array, state: EnvState, params: EnvParams) -> Array:
        r, rp = state.robots, params.robots
        num = r.x.shape[0]
        arcs = _dwa_arcs(state, params, s)
        bodies = _dwa_bodies(state, params, arcs.t)
        clearance = _dwa_clearance(arcs, bodies, params, s)
        gx, gy = _dwa_way_on(state, params, bodies, s)
        score = _dwa_score(arcs, clearance, gx, gy, state, params, s).reshape(num, -1)
        best = jnp.argmax(score, axis=1)
        any_ok = jnp.isfinite(jnp.max(score, axis=1))
        flat_v = jnp.broadcast_to(arcs.v, (num, s.speeds, s.turns)).reshape(num, -1)
        flat_w = jnp.broadcast_to(arcs.w, (num, s.speeds, s.turns)).reshape(num, -1)
        v_best = jnp.where(any_ok, jnp.take_along_axis(flat_v, best[:, None], 1)[:, 0], 0.0)
        w_best = jnp.where(any_ok, jnp.take_along_axis(flat_w, best[:, None], 1)[:, 0], 0.0)
        return _commands_to_actions(v_best, w_best, r.kin.v_forward, rp, action_dim)

    return policy


def _commands_to_actions(forward: Array, yaw_rate: Array, v_forward: Array, rp,
                         action_dim: int) -> Array:
    """Normalised actions for a forward speed (m/s) and yaw rate (rad/s); Ackermann robots
    steer for the yaw rate at their speed."""
    ackermann = rp.model == ACKERMANN
    drive = jnp.maximum(jnp.maximum(jnp.abs(v_forward), forward), 0.1)
    turn = jnp.where(ackermann, jnp.arctan(rp.wheelbase * yaw_rate / drive), yaw_rate)
    turn_limit = jnp.where(ackermann, rp.max_steering, rp.max_omega)
    a_forward = jnp.clip(forward / jnp.maximum(rp.max_speed, 1e-9), -1.0, 1.0)
    a_turn = jnp.clip(turn / jnp.maximum(turn_limit, 1e-9), -1.0, 1.0)
    if action_dim == 3:
        return jnp.stack([a_forward, jnp.zeros_like(a_forward), a_turn], axis=-1)
    return jnp.stack([a_forward, a_turn], axis=-1)


@dataclasses.dataclass(frozen=True)
class SocialForceSettings:
    """Constants of the ``social_force`` controller: the pedestrians' Moussaid 2009 law
    (``SocialForceParams`` defaults) applied to the robots, with a robot's relaxation time."""

    tau: float = 0.5  # s: relaxation toward the preferred velocity
    body_weight: float = 2.0  # how strongly a robot repels another robot or is repelled by it
    keep_right: float = 0.1  # rad the way on is turned clockwise


def social_force_controller(env: SocialNavEnv, settings: SocialForceSettings | None = None):
    """The ``social_force`` baseline policy for ``env`` (continuous actions): each robot is
    driven like a pedestrian, by the driving term toward its carrot at its top speed, the
    Moussaid 2009 interaction with the other robots (weight ``body_weight``) and the
    pedestrians, and the exponential wall term (``params.humans.forces`` constants); the
    velocity after one step, capped at its top speed, is tracked under its kinematics
    (:func:`track_velocity`)."""
    _require_continuous(env, "social_force")
    s = settings or SocialForceSettings()
    action_dim = env.config.action_dim

    def policy(obs: Array, key: Array, state: EnvState, params: EnvParams) -> Array:
        r, h, m, rp = state.robots, state.humans, params.map, params.robots
        num = r.x.shape[0]
        forces = params.humans.forces.replace(tau=s.tau)
        cx, cy = carrot_point(params.planner, state.route, state.progress)
        velocity = r.body_velocity
        vx, vy = velocity[:, 0], velocity[:, 1]
        speed = jnp.minimum(rp.max_speed, state.goal_distance / params.dt)
        # Keep right: the way on turned keep_right clockwise (exactly opposed robots otherwise
        # brake nose to nose: the law's turning term vanishes when they are aligned).
        c, si = jnp.cos(s.keep_right), jnp.sin(s.keep_right)
        ax, ay = cx - r.x, cy - r.y
        tx, ty = r.x + c * ax + si * ay, r.y - si * ax + c * ay
        fx, fy = desired_force(r.x, r.y, vx, vy, tx, ty, speed, s.tau)
        bx = jnp.concatenate([r.x, h.x])
        by = jnp.concatenate([r.y, h.y])
        bvx = jnp.concatenate([vx, h.vx])
        bvy = jnp.concatenate([vy, h.vy])
        present = jnp.concatenate([r.in_world.astype(jnp.float32) * s.body_weight,
                                   h.active.astype(jnp.float32)])
        weight = present[None, :] * (1.0 - jnp.eye(num, bx.shape[0]))
        sx, sy = moussaid_interaction(r.x, r.y, vx, vy, bx, by, bvx, bvy, weight, forces)
        away_x, away_y = point_segment_offset(r.x[:, None], r.y[:, None], m.wall_x1,
                                              m.wall_y1, m.wall_x2, m.wall_y2)
        wx, wy = exponential_wall_force(away_x, away_y, m.wall_valid, rp.radius, forces)
        nx, ny = cap_speed(vx + params.dt * (fx + sx + wx), vy + params.dt * (fy + sy + wy),
                           rp.max_speed)
        return track_velocity(nx, ny, r.heading, r.kin.v_forward, rp, 2.0, action_dim)

    return policy
