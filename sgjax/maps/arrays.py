"""A validated map compiled to padded device arrays for the jitted step."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from flax import struct
from jax import Array

from sgjax.maps.routing import all_pairs_shortest_paths, path_nodes
from sgjax.maps.schema import MapSpec

_FAR = 1.0e6  # m: where the padding wall of a wall-less map lives


@struct.dataclass
class MapArrays:
    """Map data as arrays (a pytree, so it can live in ``EnvParams``).

    Walls ``[W]`` per endpoint coordinate (a wall-less map carries one masked padding wall);
    nodes ``[N]``; ``next_hop [N, N]`` (row of the next node on the shortest path, -1 if none);
    ``path_length [N, N]`` shortest-path length in metres; ``group_starts`` / ``group_goals``
    ``[G, N]`` membership masks; ``node_gap [N, N]`` centre distance between nodes (m).
    ``max_route_nodes`` (static) bounds the node count of any shortest start-goal path.
    """

    wall_x1: Array
    wall_y1: Array
    wall_x2: Array
    wall_y2: Array
    wall_valid: Array
    node_x: Array
    node_y: Array
    next_hop: Array
    path_length: Array
    group_starts: Array
    group_goals: Array
    node_gap: Array
    max_route_nodes: int = struct.field(pytree_node=False, default=2)

    @property
    def walls(self) -> Array:
        """``[W, 4]`` segments ``(x1, y1, x2, y2)`` of the real (unpadded) walls."""
        stacked = jnp.stack([self.wall_x1, self.wall_y1, self.wall_x2, self.wall_y2], axis=-1)
        return stacked[np.asarray(self.wall_valid)]


def spawn_groups(spec: MapSpec) -> list[tuple[tuple[int, ...], tuple[int, ...]]]:
    """Groups and explicit routes as (starts, goals) row tuples; a route is a one-pair group."""
    return list(spec.groups) + [((r[0],), (r[-1],)) for r in spec.routes]


def compile_map(spec: MapSpec) -> MapArrays:
    """Compile a :class:`MapSpec` into :class:`MapArrays` (float32 / int32)."""
    walls = spec.walls
    valid = np.ones(walls.shape[0], dtype=bool)
    if walls.shape[0] == 0:
        walls = np.array([[_FAR, _FAR, _FAR + 1.0, _FAR]])
        valid = np.zeros(1, dtype=bool)
    dist, next_hop = all_pairs_shortest_paths(spec.node_positions, spec.edges)
    groups = spawn_groups(spec)
    starts = np.zeros((len(groups), spec.num_nodes), dtype=bool)
    goals = np.zeros_like(starts)
    longest = 2
    for g, (group_starts, group_goals) in enumerate(groups):
        starts[g, list(group_starts)] = True
        goals[g, list(group_goals)] = True
        for s in group_starts:
            for t in group_goals:
                if s != t:
                    longest = max(longest, len(path_nodes(next_hop, s, t)))
    pos = spec.node_positions
    gap = np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=-1)
    f32 = jnp.float32
    return MapArrays(
        wall_x1=jnp.asarray(walls[:, 0], f32),
        wall_y1=jnp.asarray(walls[:, 1], f32),
        wall_x2=jnp.asarray(walls[:, 2], f32),
        wall_y2=jnp.asarray(walls[:, 3], f32),
        wall_valid=jnp.asarray(valid),
        node_x=jnp.asarray(pos[:, 0], f32),
        node_y=jnp.asarray(pos[:, 1], f32),
        next_hop=jnp.asarray(next_hop, jnp.int32),
        path_length=jnp.asarray(np.where(np.isfinite(dist), dist, -1.0), f32),
        group_starts=jnp.asarray(starts),
        group_goals=jnp.asarray(goals),
        node_gap=jnp.asarray(gap, f32),
        max_route_nodes=longest,
    )
