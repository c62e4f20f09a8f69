"""One physics sub-step of replayed people (:mod:`sgjax.humans.replay`), in two halves around
the robots' move, as :func:`sgjax.environment.physics.advance` runs simulated pedestrians:
:func:`move_replayed` before (clocks on, people to their recorded places, the handed-over ones
under the force model) and :func:`meet_robots` after (pauses and hand-overs start, handed-over
people give way to robots, ghosts do not)."""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array

from sgjax.humans.pedestrians import (
    HumanConfig,
    HumanParams,
    HumanState,
    human_forces,
    move_humans,
    yield_to_robots,
)
from sgjax.humans.replay import deviation_from_recording, recorded_at
from sgjax.kernels.geometry import polynomial_atan2, safe_norm
from sgjax.maps.arrays import MapArrays


def move_replayed(
    config: HumanConfig, hp: HumanParams, m: MapArrays, humans: HumanState,
    robot_x: Array, robot_y: Array, robot_vx: Array, robot_vy: Array, robot_in_world: Array,
    robot_moving: Array, robot_radius: Array, dt: Array,
) -> tuple[HumanState, Array]:
    """Replayed people ``[H]`` after ``dt`` s, and the force model's cell-list overflow (int32;
    0 unless people were handed over). Each person's clock runs unless they stand in a pause;
    a person not handed over is where the recording has them at their clock (a standing one
    keeps their place at speed 0); a handed-over one moves under ``config.force_model``
    (robots ``[R]``, as :func:`~sgjax.humans.pedestrians.human_forces` takes them) and leaves
    when their track would have ended. The time each person spends away from their recorded
    place at the scene's time is booked."""
    rec, replay = hp.recording, humans.replay
    overflow = jnp.zeros((), jnp.int32)
    standing = replay.pause_left > 0.0
    clock = jnp.where(standing, replay.clock, replay.clock + dt)
    x, y, vx, vy, present = recorded_at(rec, replay.window, clock)
    vx, vy = jnp.where(standing, 0.0, vx), jnp.where(standing, 0.0, vy)
    active = present
    heading = jnp.where(vx * vx + vy * vy > 0.0025, polynomial_atan2(vy, vx), humans.heading)
    omega = jnp.zeros_like(humans.omega)
    if config.replay == "handover":
        handed = replay.handed
        # every person present is a body the handed-over ones meet
        fx, fy, turned, turn_rate, overflow = human_forces(
            config, hp, m, humans, robot_x, robot_y, robot_vx, robot_vy, robot_in_world,
            robot_moving, robot_radius, dt)
        walked = move_humans(hp, m, humans, fx, fy, dt)
        x, y = jnp.where(handed, walked.x, x), jnp.where(handed, walked.y, y)
        vx, vy = jnp.where(handed, walked.vx, vx), jnp.where(handed, walked.vy, vy)
        heading = jnp.where(handed, turned, heading)
        omega = jnp.where(handed, turn_rate, omega)
        end = rec.end[replay.window]
        active = jnp.where(handed, humans.active & (clock <= end + 1e-3), present)
    time = replay.time + dt
    replay = replay.replace(time=time, clock=clock,
                            pause_left=jnp.maximum(replay.pause_left - dt, 0.0))
    distance, counted = deviation_from_recording(rec, replay, x, y, active)
    replay = replay.replace(deviation=replay.deviation + distance * dt,
                            exposure=replay.exposure + counted.astype(jnp.float32) * dt)
    return humans.replace(x=x, y=y, vx=vx, vy=vy, active=active, heading=heading,
                          omega=omega, replay=replay), overflow


def meet_robots(
    config: HumanConfig, hp: HumanParams, m: MapArrays, humans: HumanState,
    robot_x: Array, robot_y: Array, robot_radius: Array, robot_in_world: Array,
) -> tuple[HumanState, Array]:
    """Replayed people after the robots moved (robots ``[R]``): in ``pause`` mode a person a
    robot's body touches starts standing for ``hp.pause_seconds`` (once the last pause is
    over); in ``handover`` mode a person within ``hp.handover_radius`` (body gap, m) of a robot
    is handed over for good, and the handed-over ones give way to robots as simulated
    pedestrians do. Ghosts are never moved by a robot. Returns the people and ``[R]`` flags:
    the robot's body overlaps a person's."""
    replay = humans.replay
    radius = jnp.broadcast_to(hp.radius, humans.x.shape)
    gap = (safe_norm(humans.x[:, None] - robot_x[None, :], humans.y[:, None] - robot_y[None, :])
           - radius[:, None] - robot_radius[None, :])
    overlap = humans.active[:, None] & robot_in_world[None, :] & (gap < 0.0)
    met = jnp.any(overlap, axis=0)
    if config.replay == "pause":
        touched = jnp.any(overlap, axis=1) & ~(replay.pause_left > 0.0)
        replay = replay.replace(
            pause_left=jnp.where(touched, hp.pause_seconds, replay.pause_left),
            reached=replay.reached | touched)
    if config.replay == "handover":
        near = jnp.any(humans.active[:, None] & robot_in_world[None, :]
                       & (gap < hp.handover_radius), axis=1)
        handed = replay.handed | near
        pushed, _ = yield_to_robots(hp, m, humans, robot_x, robot_y, robot_radius,
                                    robot_in_world)
        humans = humans.replace(x=jnp.where(handed, pushed.x, humans.x),
                                y=jnp.where(handed, pushed.y, humans.y))
        replay = replay.replace(handed=handed, reached=replay.reached | near)
    return humans.replace(replay=replay), met
