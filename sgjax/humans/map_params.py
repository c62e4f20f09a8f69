"""Pedestrian params for a map (``make(..., num_humans=N)`` builds them here): spawn slots,
the map's routes, wall points and the constants' defaults as float32 arrays."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from sgjax.humans.calibrated import with_constants
from sgjax.humans.groups import GroupParams, leaders
from sgjax.humans.pedestrians import HumanConfig, HumanParams
from sgjax.humans.slots import spawn_slots, wall_sample_points
from sgjax.maps.arrays import spawn_groups
from sgjax.maps.schema import MapSpec

# Pedestrian constants make() stores as float32 arrays (the dataclasses' defaults), so params
# changed or batched later keep their types.
_FLOAT_CONSTANTS = ("speed_mean", "speed_std", "speed_min", "speed_max", "max_speed_factor",
                    "waypoint_radius", "robot_weight", "orca", "hsfm")
WALL_RESOLUTION = 10.0  # wall points per metre for human_walls="points" (PySocialForce's)


def human_params(
    spec: MapSpec, config: HumanConfig, num_humans: int, radius: float,
    see_robots: bool = True, groups: tuple[int, ...] = (), constants: str = "published",
) -> HumanParams:
    """Pedestrian params for a map: spawn slots for ``radius`` (m), the map's routes, and the
    constants' defaults (``HumanParams``, ``SocialForceParams``, ``OrcaParams``,
    ``HsfmParams``, ``GroupParams``). ``see_robots`` False zeroes the robots' weight in the
    force laws and in ORCA (``robot_weight``, ``orca.robot_share``): pedestrians that do not
    see robots. ``groups``: sizes of the groups the first pedestrians walk in
    (``sgjax.humans.groups``). ``constants``: ``"published"`` or a preset of force constants
    fitted to recorded people (:mod:`sgjax.humans.calibrated`)."""
    slots, slot_nodes = spawn_slots(spec, radius) if config.max_humans else (
        np.zeros((0, 2)), np.zeros((0, 2), np.int64))
    points = (wall_sample_points(spec.walls, WALL_RESOLUTION) if config.wall_model == "points"
              else np.zeros((0, 2)))
    f32 = jnp.float32
    groups_of_routes = spec.pedestrian_groups or tuple(spawn_groups(spec))
    routes = np.asarray([(a, b) for starts, goals in groups_of_routes for a in starts
                         for b in goals if a != b] or [(0, 0)], np.int64)
    hp = HumanParams(
        num_humans=jnp.asarray(num_humans, jnp.int32),
        radius=jnp.asarray(radius, f32),
        spawn_x=jnp.asarray(slots[:, 0], f32),
        spawn_y=jnp.asarray(slots[:, 1], f32),
        spawn_nodes=jnp.asarray(slot_nodes, jnp.int32),
        wall_points_x=jnp.asarray(points[:, 0], f32),
        wall_points_y=jnp.asarray(points[:, 1], f32),
        route_start=jnp.asarray(routes[:, 0], jnp.int32),
        route_goal=jnp.asarray(routes[:, 1], jnp.int32),
    )
    hp = with_constants(hp, constants, config.force_model)  # a preset fitted to people
    if not see_robots:
        hp = hp.replace(robot_weight=0.0, orca=hp.orca.replace(robot_share=0.0))
    as_f32 = functools.partial(jax.tree.map, lambda v: jnp.asarray(v, f32))
    group_params = None
    if groups:
        leader = jnp.asarray(leaders(groups, config.max_humans))
        group_params = as_f32(GroupParams(leader=leader)).replace(leader=leader)
    return hp.replace(groups=group_params,
                      **{name: as_f32(getattr(hp, name)) for name in _FLOAT_CONSTANTS})
