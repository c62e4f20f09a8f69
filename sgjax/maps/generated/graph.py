"""Shortest routes on a generated world's graph inside ``jit``: Floyd-Warshall as a
``fori_loop`` over the padded nodes (``maps.routing.all_pairs_shortest_paths`` is its host
counterpart for loaded maps)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array

NO_PATH = -1
# A path through another node replaces the current one only when shorter by more than this
# share of it: float32 sums of equal legs differ by rounding, and the first path found stays.
TIE = 1e-6


def shortest_paths(gap: Array, adjacency: Array, hubs: int) -> tuple[Array, Array, Array]:
    """``(dist [N, N], next_hop [N, N], fits)`` over edges weighted by their length ``gap [N,
    N]`` (m, the nodes' distances): ``dist`` is ``inf`` where unreachable, ``next_hop[i, j]``
    the next node from ``i`` towards ``j`` (``NO_PATH`` where unreachable, ``i`` on the
    diagonal); ``adjacency [N, N]`` bool.

    A shortest path never passes through a node of degree 1 (it would leave by the edge it came
    in on), so Floyd-Warshall relaxes through the ``hubs`` nodes of highest degree alone: exact
    when no more than ``hubs`` nodes have degree 2 or more (``fits``; a world where more do is
    flagged, not mis-routed silently)."""
    count = gap.shape[0]
    eye = jnp.eye(count, dtype=bool)
    dist = jnp.where(eye, 0.0, jnp.where(adjacency, gap, jnp.inf))
    index = jnp.arange(count, dtype=jnp.int32)
    next_hop = jnp.where(eye | adjacency, index[None, :], NO_PATH)
    degree = jnp.sum(adjacency, axis=1)
    order = jnp.argsort(-degree, stable=True)[:hubs] if hubs < count else index

    def relax(i: Array, carry: tuple[Array, Array]) -> tuple[Array, Array]:
        dist, next_hop = carry
        k = order[i]
        through = dist[:, k][:, None] + dist[k, :][None, :]
        better = through < dist * (1.0 - TIE)
        return (jnp.where(better, through, dist),
                jnp.where(better, next_hop[:, k][:, None], next_hop))

    dist, next_hop = jax.lax.fori_loop(0, min(hubs, count), relax, (dist, next_hop))
    return dist, next_hop, jnp.sum(degree >= 2) <= hubs
