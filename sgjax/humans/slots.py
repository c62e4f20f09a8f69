"""Preparation of a map for pedestrians: spawn slots and sampled wall points, on the host for
a loaded map (:func:`spawn_slots`) and inside ``jit`` for a generated world
(:func:`world_spawn_slots`, the same slots with static capacity and a mask)."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
from flax import struct
from jax import Array

from sgjax.kernels.geometry import point_segment_distance, segments_intersect_pairs
from sgjax.maps.schema import MapSpec, point_segment_distances
from sgjax.maps.segment_grid import SegmentGrid

SPAWN_JITTER = 0.05  # m: each pedestrian starts up to this far (per axis) from its slot
SPAWN_MARGIN = 0.02  # m of free space between two pedestrians' bodies at their slots
SLOT_REACH = 1.0  # m: slots lie at most this far from a navigation-graph edge


def spawn_slots(spec: MapSpec, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Grid points where a pedestrian of ``radius`` (m) may start, and the edge beside each.

    Points are spaced so that bodies at any two slots (jitter included) do not overlap, keep
    ``radius + SPAWN_JITTER + SPAWN_MARGIN`` from every wall, lie within ``SLOT_REACH`` of a graph
    edge and see its nearest point on that edge (no wall in between: the slot is inside the
    walkable area, not behind a wall). Returns ``positions [S, 2]`` (m) and ``edge_nodes [S, 2]``
    (node rows of that edge's ends).
    """
    spacing = 2.0 * (radius + SPAWN_JITTER) + SPAWN_MARGIN
    lo, hi = spec.bounds[:2], spec.bounds[2:]
    xs = np.arange(lo[0] + 0.5 * spacing, hi[0], spacing)
    ys = np.arange(lo[1] + 0.5 * spacing, hi[1], spacing)
    gx, gy = np.meshgrid(xs, ys)
    points = np.stack([gx.ravel(), gy.ravel()], axis=-1)
    if spec.walls.shape[0]:
        # the nearest wall within the clearance (inf beyond it), through a segment grid: the
        # cost grows with the walls near each point, not points x walls
        needed = radius + SPAWN_JITTER + SPAWN_MARGIN
        clear, _ = SegmentGrid(spec.walls, max(needed, 0.5)).nearest(points, needed)
        points = points[clear >= needed]
    pos = spec.node_positions
    edges = np.asarray(spec.edges).reshape(-1, 2)
    if edges.shape[0] == 0 or points.shape[0] == 0:
        return np.zeros((0, 2)), np.zeros((0, 2), np.int64)
    segments = np.concatenate([pos[edges[:, 0]], pos[edges[:, 1]]], axis=1)
    dist = point_segment_distances(points, segments)
    nearest = dist.argmin(axis=1)
    keep = dist[np.arange(points.shape[0]), nearest] <= SLOT_REACH
    slots, slot_edges = [], []
    for point, e in zip(points[keep], nearest[keep], strict=True):
        a, b = pos[edges[e, 0]], pos[edges[e, 1]]
        t = np.clip(np.dot(point - a, b - a) / max(np.dot(b - a, b - a), 1e-12), 0.0, 1.0)
        foot = a + t * (b - a)
        if segments_intersect_pairs(np.concatenate([point, foot])[None], spec.walls).any():
            continue
        slots.append(point)
        slot_edges.append(edges[e])
    if not slots:
        return np.zeros((0, 2)), np.zeros((0, 2), np.int64)
    return np.asarray(slots), np.asarray(slot_edges, np.int64)


def wall_sample_points(walls: np.ndarray, resolution: float) -> np.ndarray:
    """Points along walls ``[W, 4]`` as PySocialForce places them (``scene.EnvState``):
    ``int(length * resolution)`` evenly spaced points per wall, both ends included.
    Returns ``[P, 2]`` (m)."""
    points = []
    for x1, y1, x2, y2 in walls:
        count = int(np.hypot(x2 - x1, y2 - y1) * resolution)
        points.append(np.stack([np.linspace(x1, x2, count), np.linspace(y1, y2, count)], -1))
    return np.concatenate(points, axis=0) if points else np.zeros((0, 2))


@struct.dataclass
class SpawnSlots:
    """A generated world's spawn slots (``[S]``, masked): positions (m), the node rows of the
    graph edge beside each ``[S, 2]``, which are slots (``valid``), and which node rows are
    the world's nodes (``node_valid [N]``: pedestrians' random goals are drawn among them)."""

    x: Array
    y: Array
    nodes: Array
    valid: Array
    node_valid: Array


def slot_grid_shape(extent: tuple[float, float, float, float], radius: float
                    ) -> tuple[int, int]:
    """``(columns, rows)`` of the slot lattice that covers any world within ``extent`` (m) for
    pedestrians of ``radius`` (m): the static capacity of :func:`world_spawn_slots`."""
    spacing = 2.0 * (radius + SPAWN_JITTER) + SPAWN_MARGIN
    return (max(1, math.ceil((extent[2] - extent[0]) / spacing)),
            max(1, math.ceil((extent[3] - extent[1]) / spacing)))


def world_spawn_slots(walls: Array, wall_valid: Array, nodes: Array, edges: Array,
                      edge_valid: Array, bounds: Array, shape: tuple[int, int],
                      radius: float, node_valid: Array) -> SpawnSlots:
    """:func:`spawn_slots` inside ``jit``: the lattice from the world's ``bounds [4]`` (m) in
    ``shape`` (:func:`slot_grid_shape`; points past the bounds masked), each point kept where
    it clears every valid wall (``walls [W, 4]``, ``wall_valid [W]``), lies within
    ``SLOT_REACH`` of a valid graph edge (``edges [E, 2]`` rows of ``nodes [N, 2]``,
    ``edge_valid [E]``) and sees that edge's nearest point. Slots are in the host function's
    order (rows of y, then x). ``node_valid [N]`` is kept as the slots' node mask."""
    spacing = 2.0 * (radius + SPAWN_JITTER) + SPAWN_MARGIN
    columns, rows = shape
    xs = bounds[0] + (0.5 + jnp.arange(columns, dtype=jnp.float32)) * spacing
    ys = bounds[1] + (0.5 + jnp.arange(rows, dtype=jnp.float32)) * spacing
    px = jnp.tile(xs, rows)
    py = jnp.repeat(ys, columns)
    inside = (px < bounds[2]) & (py < bounds[3])
    wx1, wy1, wx2, wy2 = (walls[None, :, i] for i in range(4))
    to_wall = point_segment_distance(px[:, None], py[:, None], wx1, wy1, wx2, wy2)
    clear = jnp.min(jnp.where(wall_valid[None, :], to_wall, jnp.inf), axis=1) >= (
        radius + SPAWN_JITTER + SPAWN_MARGIN)
    a, b = nodes[edges[:, 0]], nodes[edges[:, 1]]
    to_edge = point_segment_distance(px[:, None], py[:, None], a[None, :, 0], a[None, :, 1],
                                     b[None, :, 0], b[None, :, 1])
    to_edge = jnp.where(edge_valid[None, :], to_edge, jnp.inf)
    nearest = jnp.argmin(to_edge, axis=1)
    near = jnp.min(to_edge, axis=1) <= SLOT_REACH
    ea, eb = a[nearest], b[nearest]
    span = eb - ea
    point = jnp.stack([px, py], axis=-1)
    t = jnp.clip(jnp.sum((point - ea) * span, axis=-1)
                 / jnp.maximum(jnp.sum(span * span, axis=-1), 1e-12), 0.0, 1.0)
    foot = ea + t[:, None] * span
    sight = jnp.concatenate([point, foot], axis=-1)
    blocked = jnp.any(segments_intersect_pairs(sight[:, None, :], walls[None, :, :], xp=jnp)
                      & wall_valid[None, :], axis=1)
    return SpawnSlots(x=px, y=py, nodes=edges[nearest].astype(jnp.int32),
                      valid=inside & clear & near & ~blocked, node_valid=node_valid)
