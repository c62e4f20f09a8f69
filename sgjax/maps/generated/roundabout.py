"""The roundabout family: the intersection's arms (three or four by default) around a polygonal
island, robots circling the island between the arms (SocialGym 2.0's roundabout is its
intersection's plus with a diamond island in the middle)."""

from __future__ import annotations

from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from sgjax.maps.generated.family import Family, Parameter
from sgjax.maps.generated.intersection import (
    ARMS,
    SPAWNS,
    arm_groups,
    arm_spawns,
    arm_walls,
    draw_arms,
)
from sgjax.maps.generated.world import Capacity, World, padded_walls

ISLAND_SIDES = 8
RING = 2 * ARMS  # ring nodes: each arm's direction and each gap's middle
HUBS = RING + ARMS  # ring nodes and each arm's approach node
NODES = HUBS + ARMS * SPAWNS
EDGES = RING + ARMS + ARMS * SPAWNS  # the ring, each approach to its ring node, each spawn
WALLS = 4 * ARMS + ISLAND_SIDES + 1

PARAMETERS = {
    "arms": Parameter((3.0, 4.999), (2.0, 4.999), "", "the arms (the integer part)"),
    "arm_width": Parameter((3.5, 5.0), (2.4, 5.0), "m", "each arm's width (drawn per arm)"),
    "arm_length": Parameter((6.0, 9.0), (5.0, 10.0), "m", "each arm's length from the centre"),
    "angle_jitter": Parameter((0.0, 10.0), (0.0, 20.0), "deg", "how far each arm may turn "
                              "from its right angle"),
    "rotation": Parameter((0.0, 360.0), (0.0, 360.0), "deg", "the whole junction's turn"),
    "island_radius": Parameter((0.4, 0.8), (0.3, 1.5), "m", "the island's radius (an "
                               "octagon's corners)"),
}
CAPACITY = Capacity(walls=WALLS, nodes=NODES, edges=EDGES, hubs=HUBS, groups=ARMS, zones=1,
                    route_nodes=9, extent=(-13.5, -13.5, 13.5, 13.5), cell_walls=WALLS - 1)


def build(values: Mapping[str, Array], key: Array) -> World:
    """A roundabout world of the parameter ``values``; ``key`` draws the arms as the
    intersection family does and jitters the spawn lattices."""
    k_arms, k_spawn = jax.random.split(key)
    arms = draw_arms(values, k_arms)
    island = values["island_radius"]
    corner = jnp.deg2rad(values["rotation"]) + np.arange(ISLAND_SIDES + 1) * (
        2 * np.pi / ISLAND_SIDES)
    points = island * jnp.stack([jnp.cos(corner), jnp.sin(corner)], -1)
    island_walls = jnp.concatenate([points[:-1], points[1:]], -1)
    outer, outer_valid = arm_walls(arms)
    walls, valid = padded_walls(jnp.concatenate([outer, island_walls]), CAPACITY.walls,
                                jnp.concatenate([outer_valid, jnp.ones(ISLAND_SIDES, bool)]))
    # the ring halfway between the island and the narrowest arm's side, a node at each arm's
    # direction (absent arms: their right angle's) and at each gap's middle
    narrowest = jnp.min(jnp.where(arms.present, arms.half, jnp.inf))
    radius = (island + narrowest) / 2
    angle = jnp.arctan2(arms.d[:, 1], arms.d[:, 0])
    gap = jnp.mod(jnp.roll(angle, -1) - angle, 2 * np.pi)
    ring_angle = jnp.stack([angle, angle + gap / 2], 1).reshape(-1)  # [2 A] in turn
    ring = radius * jnp.stack([jnp.cos(ring_angle), jnp.sin(ring_angle)], -1)
    reach = jnp.maximum(jnp.maximum(arms.t_left, arms.t_right),
                        jnp.max(arms.half * arms.present)) + 1.0
    spawn, room = arm_spawns(arms, k_spawn, reach)
    nodes = jnp.concatenate([ring, reach[:, None] * arms.d, spawn.reshape(-1, 2)])
    arm_of, starts, goals = arm_groups(arms, HUBS)
    node_valid = jnp.concatenate([jnp.ones(RING, bool), arms.present,
                                  jnp.repeat(arms.present, SPAWNS)])
    cycle = np.stack([np.arange(RING), (np.arange(RING) + 1) % RING], 1)
    approach = np.stack([RING + np.arange(ARMS), 2 * np.arange(ARMS)], 1)  # to its ring node
    spawn_rows = HUBS + jnp.arange(ARMS * SPAWNS)
    pairs = jnp.concatenate([
        jnp.asarray(cycle, jnp.int32), jnp.asarray(approach, jnp.int32),
        jnp.stack([RING + arm_of[spawn_rows].astype(jnp.int32), spawn_rows.astype(jnp.int32)],
                  1)])
    r = jnp.max(arms.half * arms.present) + 0.5
    return World(
        walls=walls, wall_valid=valid, nodes=nodes, node_valid=node_valid, edges=pairs,
        edge_valid=node_valid[pairs[:, 0]] & node_valid[pairs[:, 1]], group_starts=starts,
        group_goals=goals, zones=jnp.stack([-r, -r, r, r])[None],
        zone_width=(narrowest - island)[None], zone_valid=jnp.ones(1, bool),
        bounds=jnp.asarray([-13.5, -13.5, 13.5, 13.5]),
        made=room, dilemma=jnp.asarray(True))


ROUNDABOUT = Family("roundabout", "three or four corridors around a polygonal island; robots "
                    "circle it from one arm's end to another's", PARAMETERS, CAPACITY, build)
