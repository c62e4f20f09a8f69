"""The open-space family: a walled arena with up to four box obstacles in its middle, robots on
a ring inside the walls going to any other ring point, so flows cross in the middle (SocialGym
2.0's open map is an arena without obstacles). The graph is made by visibility: ring points and
points off each obstacle's corners, joined wherever the straight line keeps clear of every
wall."""

from __future__ import annotations

from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from sgjax.kernels.geometry import point_segment_distance
from sgjax.maps.generated.family import Family, Parameter
from sgjax.maps.generated.world import Capacity, World, padded_walls

RING = 24  # spawn points on the ring
BOXES = 4  # obstacle capacity
CELLS = 3  # the middle square is cut into CELLS x CELLS cells; each box takes its own
CORNER_GAP = 0.5  # m: corner nodes stand this far off a box's corners (each way)
EDGE_CLEARANCE = 0.35  # m: an edge keeps this far from every box (from its corners' circle)
RING_GAP = 1.2  # m: the ring's distance from the nearest arena wall
NODES = RING + 4 * BOXES
WALLS = 4 + 4 * BOXES + 1
PAIRS = np.stack(np.triu_indices(NODES, 1), axis=1).astype(np.int32)  # every candidate edge

PARAMETERS = {
    "arena_size": Parameter((10.0, 16.0), (8.0, 20.0), "m", "the square arena's side"),
    "obstacles": Parameter((0.0, 4.999), (0.0, 4.999), "", "box obstacles (the integer part)"),
    "obstacle_size": Parameter((0.3, 0.8), (0.2, 1.0), "", "a box's half side, a fraction of "
                               "the most its cell allows"),
}
CAPACITY = Capacity(walls=WALLS, nodes=NODES, edges=len(PAIRS), hubs=NODES, groups=1, zones=1,
                    route_nodes=8,
                    extent=(-10.5, -10.5, 10.5, 10.5), cell_walls=WALLS - 1)


def build(values: Mapping[str, Array], key: Array) -> World:
    """An open-space world of the parameter ``values``; ``key`` places the boxes and turns the
    ring."""
    half = values["arena_size"] / 2
    count = jnp.floor(values["obstacles"]).astype(jnp.int32)
    k_cells, k_jitter, k_turn = jax.random.split(key, 3)
    cell = values["arena_size"] / 2 / CELLS  # the middle square is half the arena's side
    cells = jax.random.permutation(k_cells, CELLS * CELLS)[:BOXES]
    cx = -half / 2 + (cells % CELLS + 0.5) * cell
    cy = -half / 2 + (cells // CELLS + 0.5) * cell
    most = jnp.maximum(cell / 2 - CORNER_GAP - 0.05, 0.1)  # corner nodes stay in the cell
    size = values["obstacle_size"] * most
    shift = jax.random.uniform(k_jitter, (BOXES, 2), jnp.float32, -1.0, 1.0) * (most - size)
    cx, cy = cx + shift[:, 0], cy + shift[:, 1]
    present = jnp.arange(BOXES) < count
    x0, x1, y0, y1 = cx - size, cx + size, cy - size, cy + size
    boxes = jnp.stack([jnp.stack([x0, y0, x1, y0], -1), jnp.stack([x1, y0, x1, y1], -1),
                       jnp.stack([x1, y1, x0, y1], -1), jnp.stack([x0, y1, x0, y0], -1)],
                      axis=1).reshape(-1, 4)
    arena = jnp.stack([jnp.stack([-half, -half, half, -half]),
                       jnp.stack([half, -half, half, half]),
                       jnp.stack([half, half, -half, half]),
                       jnp.stack([-half, half, -half, -half])])
    walls, valid = padded_walls(jnp.concatenate([arena, boxes]), CAPACITY.walls,
                                jnp.concatenate([jnp.ones(4, bool), jnp.repeat(present, 4)]))
    turn = jax.random.uniform(k_turn, (), jnp.float32, 0.0, 2 * np.pi / RING)
    angle = turn + jnp.arange(RING) * (2 * np.pi / RING)
    radius = half - RING_GAP
    ring = jnp.stack([radius * jnp.cos(angle), radius * jnp.sin(angle)], -1)
    # the ring keeps RING_GAP from the walls at the sides' middles, more towards the corners
    off = size + CORNER_GAP
    corners = jnp.stack([jnp.stack([cx - off, cy - off], -1), jnp.stack([cx + off, cy - off], -1),
                         jnp.stack([cx + off, cy + off], -1), jnp.stack([cx - off, cy + off], -1)],
                        axis=1).reshape(-1, 2)
    nodes = jnp.concatenate([ring, corners])
    node_valid = jnp.concatenate([jnp.ones(RING, bool), jnp.repeat(present, 4)])
    # visibility: a candidate edge is kept where it keeps EDGE_CLEARANCE from the circle
    # through each present box's corners (conservative: no wall is nearer); the ring lies
    # inside the arena, so no chord between its points comes near the arena's walls
    a, b = nodes[PAIRS[:, 0]], nodes[PAIRS[:, 1]]
    gap = point_segment_distance(cx[None], cy[None], a[:, 0:1], a[:, 1:2], b[:, 0:1],
                                 b[:, 1:2])  # [E, BOXES]
    clear = jnp.all(~present[None] | (gap >= size[None] * np.sqrt(2.0) + EDGE_CLEARANCE),
                    axis=1)
    edge_valid = node_valid[PAIRS[:, 0]] & node_valid[PAIRS[:, 1]] & clear
    in_ring = jnp.arange(NODES) < RING
    zone = jnp.stack([-half / 2, -half / 2, half / 2, half / 2])
    return World(
        walls=walls, wall_valid=valid, nodes=nodes, node_valid=node_valid,
        edges=jnp.asarray(PAIRS), edge_valid=edge_valid, group_starts=in_ring[None],
        group_goals=in_ring[None],
        zones=zone[None], zone_width=values["arena_size"][None] / 2,
        zone_valid=jnp.ones(1, bool),
        bounds=jnp.stack([-half - 0.5, -half - 0.5, half + 0.5, half + 0.5]),
        made=jnp.asarray(True), dilemma=jnp.asarray(True))


OPEN = Family("open", "a walled arena with up to four box obstacles; robots cross between "
              "ring points", PARAMETERS, CAPACITY, build)
