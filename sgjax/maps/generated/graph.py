"""Shortest routes on a generated world's graph inside ``jit``: Floyd-Warshall as a
``fori_loop`` over the padded hub nodes (``maps.routing.all_pairs_shortest_paths`` is its host
counterpart for loaded maps)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array

from sgjax.maps.routing import NO_PATH

# A path through another node replaces the current one only when shorter by more than this
# share of it: float32 sums of equal legs differ by rounding, and the first path found stays.
TIE = 1e-6
# From this many hubs on, Floyd-Warshall runs over the hubs' own matrix and the other nodes
# are hung off them afterwards (a few N x N gathers: dearer than the whole-matrix loop with
# the mini-games' 2 to 5 hubs, cheaper with the floor plans' 64).
HUBS_APART = 16


def relaxed(gap: Array, adjacency: Array, order: Array) -> tuple[Array, Array]:
    """``(dist, next_hop)`` of every node pair, relaxing through the nodes ``order`` (node
    rows, in that order) on the whole ``[N, N]`` matrix."""
    count = gap.shape[0]
    eye = jnp.eye(count, dtype=bool)
    dist = jnp.where(eye, 0.0, jnp.where(adjacency, gap, jnp.inf))
    index = jnp.arange(count, dtype=jnp.int32)
    next_hop = jnp.where(eye | adjacency, index[None, :], NO_PATH)

    def relax(i: Array, carry: tuple[Array, Array]) -> tuple[Array, Array]:
        dist, next_hop = carry
        k = order[i]
        through = dist[:, k][:, None] + dist[k, :][None, :]
        better = through < dist * (1.0 - TIE)
        return (jnp.where(better, through, dist),
                jnp.where(better, next_hop[:, k][:, None], next_hop))

    return jax.lax.fori_loop(0, order.shape[0], relax, (dist, next_hop))


def shortest_paths(gap: Array, adjacency: Array, hubs: int) -> tuple[Array, Array, Array]:
    """``(dist [N, N], next_hop [N, N], fits)`` over edges weighted by their length ``gap [N,
    N]`` (m, the nodes' distances): ``dist`` is ``inf`` where unreachable, ``next_hop[i, j]``
    the next node from ``i`` towards ``j`` (``NO_PATH`` where unreachable, ``i`` on the
    diagonal); ``adjacency [N, N]`` bool.

    A shortest path never passes through a node of degree 1 (it would leave by the edge it came
    in on), so Floyd-Warshall relaxes through the ``hubs`` nodes of highest degree alone, in
    that order. With :data:`HUBS_APART` hubs or more (and fewer than the nodes) it runs over
    the hubs' own matrix (``hubs^3`` work, not ``hubs N^2``): every other node hangs off the hub
    it is joined to (its anchor), its routes its edge to the anchor and the anchor's. Exact
    when no more than ``hubs`` nodes have degree 2 or more (``fits``; a world where more do is
    flagged, not mis-routed silently)."""
    count = gap.shape[0]
    degree = jnp.sum(adjacency, axis=1)
    fits = jnp.sum(degree >= 2) <= hubs
    ranked = jnp.argsort(-degree, stable=True).astype(jnp.int32)
    if hubs < HUBS_APART or hubs >= count:  # relax through the hubs on the whole matrix
        return (*relaxed(gap, adjacency, ranked[:min(hubs, count)]), fits)
    index = jnp.arange(count, dtype=jnp.int32)
    order = ranked[:hubs]  # hub -> node
    hub_of = jnp.full(count, -1, jnp.int32).at[order].set(jnp.arange(hubs, dtype=jnp.int32))
    hub_dist, hub_hop = relaxed(gap[order][:, order], adjacency[order][:, order],
                                 jnp.arange(hubs, dtype=jnp.int32))
    is_hub = hub_of >= 0
    neighbour = jnp.argmax(adjacency, axis=1).astype(jnp.int32)  # a leaf's one neighbour
    anchor = jnp.where(is_hub, index, jnp.where((degree >= 1) & is_hub[neighbour], neighbour,
                                                -1))
    hooked = anchor >= 0
    offset = jnp.where(is_hub, 0.0, gap[index, neighbour])  # m from a node to its anchor
    a = hub_of[jnp.maximum(anchor, 0)]  # each node's anchor among the hubs
    via = offset[:, None] + hub_dist[a][:, a] + offset[None, :]
    via = jnp.where(hooked[:, None] & hooked[None, :], via, jnp.inf)
    eye = jnp.eye(count, dtype=bool)
    dist = jnp.where(eye, 0.0, jnp.minimum(via, jnp.where(adjacency, gap, jnp.inf)))
    # the next node: off a leaf, its anchor (or the leaf it alone is joined to); off a hub,
    # the leaf hanging off it, or the hub route's next hub towards the goal's anchor
    step = hub_hop[jnp.maximum(hub_of, 0)][:, a]  # [N, N] among the hubs
    from_hub = jnp.where(a[None, :] == a[:, None], index[None, :],
                         order[jnp.maximum(step, 0)])
    from_leaf = jnp.where(hooked, anchor, neighbour)[:, None]
    next_hop = jnp.where(is_hub[:, None], from_hub, from_leaf)
    next_hop = jnp.where(eye, index[:, None], jnp.where(jnp.isfinite(dist), next_hop, NO_PATH))
    return dist, next_hop, fits
