"""One integrator for diff-drive, omnidirectional and Ackermann robots under their limits.

Every robot carries the same body-frame kinematic state (forward speed, lateral speed, yaw rate,
steering angle); ``RobotParams.model`` decides which parts a robot may use, so a mixed team is one
array program with no branching.

Commands (physical units, clipped to the limits):
  * ``forward`` (m/s), body x; reverse allowed down to ``-max_reverse_speed``;
  * ``lateral`` (m/s), body y; omnidirectional robots only (ignored otherwise);
  * ``turn``: yaw rate (rad/s) for diff drive and omni, steering angle (rad) for Ackermann.

Per step of ``dt`` seconds: linear velocity moves toward the command by at most ``max_accel * dt``
when speeding up in the same direction, else ``max_decel * dt`` (a vector limit for omni robots);
diff drive and omni yaw rate moves by at most ``max_alpha * dt`` and stays within ``max_omega``;
Ackermann steering moves by at most ``max_steer_rate * dt`` within
``atan(wheelbase / min_turn_radius)``,
and its yaw rate is ``v tan(steering) / wheelbase`` (kinematic bicycle about the rear axle), capped
at ``max_omega``. Positions integrate with the mid-step heading.
"""

from __future__ import annotations

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.dynamics.limits import ACKERMANN, OMNIDIRECTIONAL, RobotParams
from sgjax.kernels.geometry import safe_norm, wrap_angle


@struct.dataclass
class Kinematics:
    """Body-frame motion state, each ``[R]``: heading (rad), speeds (m/s), yaw rate (rad/s),
    steering angle (rad, Ackermann only)."""

    heading: Array
    v_forward: Array
    v_lateral: Array
    omega: Array
    steering: Array


def clip_command(
    forward: Array, lateral: Array, turn: Array, p: RobotParams
) -> tuple[Array, Array, Array]:
    """Clip commands to each robot's limits (see the module docstring for units)."""
    omni = p.model == OMNIDIRECTIONAL
    forward = jnp.clip(forward, -p.max_reverse_speed, p.max_speed)
    lateral = jnp.where(omni, jnp.clip(lateral, -p.max_speed, p.max_speed), 0.0)
    speed = safe_norm(forward, lateral)
    shrink = jnp.where(omni & (speed > p.max_speed), p.max_speed / jnp.maximum(speed, 1e-9), 1.0)
    turn_limit = jnp.where(p.model == ACKERMANN, p.max_steering, p.max_omega)
    return forward * shrink, lateral * shrink, jnp.clip(turn, -turn_limit, turn_limit)


def integrate(
    kin: Kinematics, forward: Array, lateral: Array, turn: Array, p: RobotParams, dt: Array
) -> tuple[Kinematics, Array, Array]:
    """Advance every robot by ``dt`` under its limits.

    Returns the new kinematics and the world-frame displacement ``(dx, dy)`` (m), before contacts.
    """
    forward, lateral, turn = clip_command(forward, lateral, turn, p)
    dvf, dvl = forward - kin.v_forward, lateral - kin.v_lateral
    change = safe_norm(dvf, dvl)
    same_direction = forward * kin.v_forward + lateral * kin.v_lateral >= 0.0
    speeding_up = same_direction & (
        safe_norm(forward, lateral) > safe_norm(kin.v_forward, kin.v_lateral)
    )
    max_change = jnp.where(speeding_up, p.max_accel, p.max_decel) * dt
    scale = jnp.minimum(1.0, max_change / jnp.maximum(change, 1e-9))
    v_forward = kin.v_forward + dvf * scale
    v_lateral = kin.v_lateral + dvl * scale

    ackermann = p.model == ACKERMANN
    steer_step = jnp.clip(turn - kin.steering, -p.max_steer_rate * dt, p.max_steer_rate * dt)
    steering = jnp.where(ackermann, kin.steering + steer_step, 0.0)
    omega_ackermann = v_forward * jnp.tan(steering) / p.wheelbase
    omega_step = jnp.clip(turn - kin.omega, -p.max_alpha * dt, p.max_alpha * dt)
    omega = jnp.where(ackermann, omega_ackermann, kin.omega + omega_step)
    omega = jnp.clip(omega, -p.max_omega, p.max_omega)

    mid = kin.heading + 0.5 * omega * dt
    cos_m, sin_m = jnp.cos(mid), jnp.sin(mid)
    dx = (v_forward * cos_m - v_lateral * sin_m) * dt
    dy = (v_forward * sin_m + v_lateral * cos_m) * dt
    new = Kinematics(
        heading=wrap_angle(kin.heading + omega * dt),
        v_forward=v_forward,
        v_lateral=v_lateral,
        omega=omega,
        steering=steering,
    )
    return new, dx, dy


def stop_on_contact(kin: Kinematics, hit: Array, p: RobotParams) -> Kinematics:
    """A robot that hit something stops at once (linear speeds zero), like a bumper. Diff-drive
    and omni robots keep their yaw rate; an Ackermann robot's yaw rate follows its speed."""
    v_forward = jnp.where(hit, 0.0, kin.v_forward)
    omega = jnp.where(hit & (p.model == ACKERMANN), 0.0, kin.omega)
    return kin.replace(v_forward=v_forward, v_lateral=jnp.where(hit, 0.0, kin.v_lateral),
                       omega=omega)


def decode_continuous(action: Array, p: RobotParams, action_dim: int) -> tuple[Array, Array, Array]:
    """Map normalised actions ``[R, action_dim]`` in [-1, 1] to ``(forward, lateral, turn)``.

    ``action_dim`` 2 is ``(forward, turn)``; 3 is ``(forward, lateral, turn)``. ``forward`` scales
    by ``max_speed`` when positive and ``max_reverse_speed`` when negative; ``lateral`` by
    ``max_speed`` (omnidirectional robots only; others ignore it); ``turn`` by ``max_omega``
    (steering limit for Ackermann). Values outside
    [-1, 1] are clipped to the box.
    """
    a = jnp.clip(action, -1.0, 1.0)
    f = a[:, 0]
    forward = jnp.where(f >= 0.0, f * p.max_speed, f * p.max_reverse_speed)
    omni = p.model == OMNIDIRECTIONAL
    lateral = jnp.where(omni, a[:, 1] * p.max_speed, 0.0) if action_dim == 3 else jnp.zeros_like(f)
    turn_limit = jnp.where(p.model == ACKERMANN, p.max_steering, p.max_omega)
    return forward, lateral, a[:, -1] * turn_limit
