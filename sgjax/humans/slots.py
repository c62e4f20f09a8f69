"""Host-side preparation of a map for pedestrians: spawn slots and sampled wall points."""

from __future__ import annotations

import numpy as np

from sgjax.kernels.geometry import segments_intersect_pairs
from sgjax.maps.schema import MapSpec, point_segment_distances

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
        clear = point_segment_distances(points, spec.walls).min(axis=1)
        points = points[clear >= radius + SPAWN_JITTER + SPAWN_MARGIN]
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
