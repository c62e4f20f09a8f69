"""One step of motion for every body: the sub-step loop of the environment.

Each of ``substeps`` sub-steps of ``dt / substeps`` s moves pedestrians by their social forces,
integrates each robot's commands under its own limits, separates overlapping robots, clamps every
robot to the walls (swept: nobody passes through a wall), lets pedestrians yield to robots, and
stops robots whose bumpers touch something. Only ``moving`` robots (active, or settling on
their goal) move; the others keep their state. Parked robots (``RobotState.parked``) are static
bodies: pedestrians avoid them and moving robots are pushed off them, but they never move.
Shapes: ``R`` robots, ``H`` pedestrians; SI units.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.dynamics.models import integrate, stop_on_contact
from sgjax.humans.pedestrians import (
    HumanConfig,
    HumanState,
    human_forces,
    move_humans,
    yield_to_robots,
)
from sgjax.humans.replay_step import meet_robots, move_replayed
from sgjax.kernels.contacts import clamp_to_walls, separate_robots
from sgjax.types import EnvParams, RobotState


@struct.dataclass
class Commands:
    """Decoded actions, ``[R]`` each: forward speed / acceleration command, lateral command
    (omnidirectional robots) and turn command, as ``sgjax.dynamics.integrate`` reads them."""

    forward: Array
    lateral: Array
    turn: Array


@struct.dataclass
class Contacts:
    """``robot, wall, human`` ``[R]`` bool: what each robot touched at any sub-step of the
    step; ``neighbor_overflow`` int32 scalar: the most bodies any sub-step left out of a full
    neighbour cell list (:mod:`sgjax.humans.neighbors`; 0 when every list fit)."""

    robot: Array
    wall: Array
    human: Array
    neighbor_overflow: Array


def advance(
    robots: RobotState, humans: HumanState, commands: Commands, params: EnvParams,
    substeps: int, contact_passes: int, human_config: HumanConfig,
) -> tuple[RobotState, HumanState, Contacts]:
    """Move robots and pedestrians through one step of ``params.dt`` s.

    ``substeps`` and ``contact_passes`` (robot-robot separation passes per sub-step) are static;
    ``human_config.max_humans == 0`` skips the pedestrians. Returns the moved robots (position
    and kinematics; the flags are unchanged), the moved pedestrians and the contacts.
    """
    rp = params.robots
    moving, in_world = robots.moving, robots.in_world
    dt_sub = params.dt / substeps
    num_robots = robots.x.shape[0]
    x, y, kin = robots.x, robots.y, robots.kin
    touched = Contacts(*(jnp.zeros(num_robots, bool),) * 3, jnp.zeros((), jnp.int32))
    for _ in range(substeps):
        overflow = jnp.zeros((), jnp.int32)
        if human_config.max_humans:
            velocity = robots.replace(kin=kin).body_velocity
            robot_bodies = (x, y, velocity[:, 0], velocity[:, 1], in_world, moving, rp.radius)
            if human_config.replay:
                humans, overflow = move_replayed(human_config, params.humans, params.map,
                                                 humans, *robot_bodies, dt_sub)
            else:
                fx, fy, heading, omega, overflow = human_forces(
                    human_config, params.humans, params.map, humans, *robot_bodies, dt_sub)
                humans = move_humans(params.humans, params.map, humans, fx, fy,
                                     dt_sub).replace(heading=heading, omega=omega)
        new_kin, dx, dy = integrate(kin, commands.forward, commands.lateral, commands.turn, rp,
                                    dt_sub)
        dx, dy = jnp.where(moving, dx, 0.0), jnp.where(moving, dy, 0.0)
        push_x, push_y, overlap = separate_robots(x + dx, y + dy, rp.radius, in_world, moving)
        dx, dy, wall = clamp_to_walls(x, y, dx + push_x, dy + push_y, rp.radius, params.map)
        x, y = x + dx, y + dy
        # Optional relaxation: a robot pinned against a wall cannot take its half of a push, so
        # the overlap left over is split again (each pass halves what a pinned pair leaves).
        # Robots in contact also stop (below), which bounds what is left.
        for _ in range(contact_passes - 1):
            push_x, push_y, _ = separate_robots(x, y, rp.radius, in_world, moving)
            push_x, push_y, pinned = clamp_to_walls(x, y, push_x, push_y, rp.radius, params.map)
            x, y, wall = x + push_x, y + push_y, wall | pinned
        if human_config.replay:
            humans, met = meet_robots(human_config, params.humans, params.map, humans, x, y,
                                      rp.radius, in_world)
        elif human_config.max_humans:
            humans, met = yield_to_robots(params.humans, params.map, humans, x, y, rp.radius,
                                          in_world)
        else:
            met = jnp.zeros(num_robots, bool)
        # Bumpers: a robot touching a wall, another robot or a pedestrian stops.
        new_kin = stop_on_contact(new_kin, wall | overlap | met, rp)
        kin = jax.tree.map(lambda new, old: jnp.where(moving, new, old), new_kin, kin)
        touched = Contacts(robot=touched.robot | (overlap & moving),
                           wall=touched.wall | (wall & moving),
                           human=touched.human | (met & moving),
                           neighbor_overflow=jnp.maximum(touched.neighbor_overflow, overflow))
    return robots.replace(x=x, y=y, kin=kin), humans, touched
