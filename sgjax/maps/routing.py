"""Shortest paths on the navigation graph, computed once on the host (numpy)."""

from __future__ import annotations

import numpy as np

NO_PATH = -1


def connected_components(num_nodes: int, edges: np.ndarray) -> np.ndarray:
    """Component label per node, ``[N]`` int."""
    label = np.arange(num_nodes)

    def find(i: int) -> int:
        while label[i] != i:
            label[i] = label[label[i]]
            i = label[i]
        return i

    for a, b in edges:
        ra, rb = find(int(a)), find(int(b))
        if ra != rb:
            label[max(ra, rb)] = min(ra, rb)
    return np.array([find(i) for i in range(num_nodes)])


def all_pairs_shortest_paths(
    positions: np.ndarray, edges: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Floyd-Warshall over edges weighted by Euclidean length.

    Returns ``(dist [N, N] metres, inf where unreachable; next_hop [N, N] int, NO_PATH where
    unreachable, and ``next_hop[i, i] == i``)``.
    """
    n = positions.shape[0]
    dist = np.full((n, n), np.inf)
    next_hop = np.full((n, n), NO_PATH, dtype=np.int64)
    np.fill_diagonal(dist, 0.0)
    next_hop[np.arange(n), np.arange(n)] = np.arange(n)
    for a, b in edges:
        w = float(np.linalg.norm(positions[a] - positions[b]))
        for u, v in ((a, b), (b, a)):
            if w < dist[u, v]:
                dist[u, v] = w
                next_hop[u, v] = v
    for k in range(n):
        through = dist[:, k : k + 1] + dist[k : k + 1, :]
        better = through < dist - 1e-12
        dist = np.where(better, through, dist)
        next_hop = np.where(better, next_hop[:, k : k + 1], next_hop)
    return dist, next_hop


def path_nodes(next_hop: np.ndarray, start: int, goal: int) -> list[int]:
    """Node rows of the shortest path from ``start`` to ``goal`` (inclusive)."""
    if next_hop[start, goal] == NO_PATH:
        raise ValueError(f"no path from node row {start} to node row {goal}")
    path = [start]
    while path[-1] != goal:
        path.append(int(next_hop[path[-1], goal]))
    return path
