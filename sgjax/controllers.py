"""Classical continuous-action controllers for the robots, as policies
(``policy(obs, key, state, params) -> actions [R, d]`` in [-1, 1]; jittable, vmappable).

``orca``: every robot takes the ORCA velocity (:mod:`sgjax.orca`; van den Berg et al. 2011)
toward its pure-pursuit carrot on its route, avoiding the other robots (reciprocally: they run
the same controller; parked robots are static), pedestrians (all of the avoidance: they may not
reciprocate) and the nearest walls (:func:`sgjax.orca.wall_lines`), then tracks that velocity
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
from sgjax.geometry import point_segment_offset, safe_norm, wrap_angle
from sgjax.orca import orca_velocity, wall_lines
from sgjax.planner import carrot_point

if TYPE_CHECKING:
    from sgjax.env import SocialNavEnv
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
        gap_sq = jnp.square(bx[None, :] - r.x[:, None]) + jnp.square(by[None, :] - r.y[:, None])
        k = min(s.neighbors, bx.shape[0] - 1)
        if k > 0:
            _, near = jax.lax.top_k(jnp.where(pair, -gap_sq, -jnp.inf), k)
            near_valid = jnp.take_along_axis(pair, near, axis=1)
        else:
            near = jnp.zeros((num, 0), jnp.int32)
            near_valid = jnp.zeros((num, 0), bool)
        ox, oy = point_segment_offset(r.x[:, None], r.y[:, None], m.wall_x1, m.wall_y1,
                                      m.wall_x2, m.wall_y2)
        wall_gap = jnp.where(m.wall_valid[None, :], ox * ox + oy * oy, jnp.inf)
        kw = min(s.walls, m.wall_x1.shape[0])
        _, wall_near = jax.lax.top_k(-wall_gap, kw)
        wall_valid = jnp.take_along_axis(jnp.isfinite(wall_gap), wall_near, axis=1)

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
