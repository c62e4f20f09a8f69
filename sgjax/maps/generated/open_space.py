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

from sgjax.kernels.geometry import point_segment_distance, segments_intersect_pairs
from sgjax.maps.generated.family import Family, Parameter
from sgjax.maps.generated.world import Capacity, World, padded_walls

RING = 24  # spawn points on the ring
BOXES = 4  # obstacle capacity
CELLS = 3  # the middle square is cut into CELLS x CELLS cells; each box takes its own
CORNER_GAP = 0.5  # m: corner nodes stand this far off a box's corners (each way)
EDGE_CLEARANCE = 0.35  # m: an edge keeps this far from every wall
RING_GAP = 1.2  # m: the ring's distance from the nearest arena wall
NODES = RING + 4 * BOXES
WALLS = 4 + 4 * BOXES + 1

PARAMETERS = {
    "arena_size": Parameter((10.0, 16.0), (8.0, 20.0), "m", "the square arena's side"),
    "obstacles": Parameter((0.0, 4.999), (0.0, 4.999), "", "box obstacles (the integer part)"),
    "obstacle_size": Parameter((0.3, 0.8), (0.2, 1.0), "", "a box's half side, a fraction of "
                               "the most its cell allows"),
}
CAPACITY = Capacity(walls=WALLS, nodes=NODES, groups=1, zones=1, route_nodes=8,
                    extent=(-10.5, -10.5, 10.5, 10.5), cell_walls=WALLS - 1)


def segment_gaps(a: Array, b: Array) -> Array:
    """Distances (m) between segments ``a [..., 4]`` and ``b [..., 4]`` (broadcast), 0 where
    they cross."""
    def ends_to(p: Array, q: Array) -> Array:
        return jnp.minimum(
            point_segment_distance(p[..., 0], p[..., 1], q[..., 0], q[..., 1], q[..., 2],
                                   q[..., 3]),
            point_segment_distance(p[..., 2], p[..., 3], q[..., 0], q[..., 1], q[..., 2],
                                   q[..., 3]))

    gap = jnp.minimum(ends_to(a, b), ends_to(b, a))
    return jnp.where(segments_intersect_pairs(a, b, xp=jnp), 0.0, gap)


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
    walls, valid = padded_walls(jnp.concatenate([arena, boxes]), CAPACITY.walls)
    valid = valid & jnp.concatenate([jnp.ones(4, bool), jnp.repeat(present, 4),
                                     jnp.zeros(1, bool)])
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
    segments = jnp.concatenate([jnp.broadcast_to(nodes[:, None], (NODES, NODES, 2)),
                                jnp.broadcast_to(nodes[None], (NODES, NODES, 2))], -1)
    gaps = segment_gaps(segments[:, :, None, :], walls[None, None])  # [N, N, W]
    clear = jnp.all(~valid[None, None] | (gaps >= EDGE_CLEARANCE), axis=-1)
    pair = node_valid[:, None] & node_valid[None, :] & ~jnp.eye(NODES, dtype=bool)
    in_ring = jnp.arange(NODES) < RING
    zone = jnp.stack([-half / 2, -half / 2, half / 2, half / 2])
    return World(
        walls=walls, wall_valid=valid, nodes=nodes, node_valid=node_valid,
        adjacency=pair & clear, group_starts=in_ring[None], group_goals=in_ring[None],
        zones=zone[None], zone_width=values["arena_size"][None] / 2,
        bounds=jnp.stack([-half - 0.5, -half - 0.5, half + 0.5, half + 0.5]),
        made=jnp.asarray(True), dilemma=jnp.asarray(True))


OPEN = Family("open", "a walled arena with up to four box obstacles; robots cross between "
              "ring points", PARAMETERS, CAPACITY, build)
