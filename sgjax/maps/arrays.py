"""A validated map compiled to padded device arrays for the jitted step."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from flax import struct
from jax import Array
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from sgjax.kernels.geometry import segments_intersect
from sgjax.maps.routing import all_pairs_shortest_paths, path_nodes
from sgjax.maps.schema import MapSpec, point_segment_distances
from sgjax.maps.segment_grid import SegmentGrid, pair_distances, unique_pairs

FAR = 1.0e6  # m: where padding walls (and a generated world's padding zones) live


@struct.dataclass
class MapArrays:
    """Map data as arrays (a pytree, so it can live in ``EnvParams``).

    Walls ``[W + 1]`` per endpoint coordinate (the last is a masked padding wall far away);
    nodes ``[N]``; ``next_hop [N, N]`` (row of the next node on the shortest path, -1 if none);
    ``path_length [N, N]`` shortest-path length in metres; ``group_starts`` / ``group_goals``
    ``[G, N]`` membership masks; ``node_gap [N, N]`` centre distance between nodes (m).
    ``max_route_nodes`` (static) bounds the node count of any shortest start-goal path.
    ``cell_walls`` lists, for each cell of a ``grid_shape`` grid of ``cell_size`` m squares from
    ``grid_origin``, the walls within ``reach`` m of the cell (what the planner checks).
    ``zone_rect [Z, 4]`` holds the map's conflict zones in file order, ``zone_width [Z]`` the
    free width of each (:func:`zone_widths`).
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
    cell_walls: Array  # [C, Kw] int32: walls within reach of each grid cell (padded, masked)
    grid_origin: Array  # [2] m: lower-left corner of the wall grid
    zone_rect: Array  # [Z, 4] conflict zones (xmin, ymin, xmax, ymax) in m; Z may be 0
    zone_width: Array  # [Z] m: free width of the passage each zone guards (zone_widths)
    max_route_nodes: int = struct.field(pytree_node=False, default=2)
    grid_shape: tuple[int, int] = struct.field(pytree_node=False, default=(1, 1))
    cell_size: float = struct.field(pytree_node=False, default=1.0)
    # m: every wall within this distance of a point is in its cell's list (0: not promised, so
    # nothing but the planner may read the lists)
    reach: float = struct.field(pytree_node=False, default=0.0)

    def cell_of(self, x: Array, y: Array) -> Array:
        """Flat grid-cell index of points (clipped to the grid)."""
        nx, ny = self.grid_shape
        ix = jnp.clip(jnp.floor((x - self.grid_origin[0]) / self.cell_size), 0, nx - 1)
        iy = jnp.clip(jnp.floor((y - self.grid_origin[1]) / self.cell_size), 0, ny - 1)
        return (iy * nx + ix).astype(jnp.int32)

    @property
    def walls(self) -> Array:
        """``[W, 4]`` segments ``(x1, y1, x2, y2)`` of the real (unpadded) walls."""
        stacked = jnp.stack([self.wall_x1, self.wall_y1, self.wall_x2, self.wall_y2], axis=-1)
        return stacked[np.asarray(self.wall_valid)]


def spawn_groups(spec: MapSpec) -> list[tuple[tuple[int, ...], tuple[int, ...]]]:
    """Groups and explicit routes as (starts, goals) row tuples.

    Routes are folded into groups that allow exactly their (start, goal) pairs: starts with the
    same goals share a group, and starts whose goals are "every member but me" of one set
    (SocialGym's open map: every ordered pair of 48 nodes, 2256 routes) share a group of that set
    (a group never pairs a start with itself), so SocialGym's scenarios become one or two groups
    instead of hundreds or thousands. Drawing a group by free starts x free goals, then a start and
    a goal in it, is close to SocialGym's ``ManualScenario`` (a free route uniformly): the same for
    a product of starts and goals with nothing taken yet; otherwise a group's weight also counts
    its start = goal pairs, and taken goals shift the odds within it.
    """
    goals_of: dict[int, set[int]] = {}
    for route in spec.routes:
        goals_of.setdefault(route[0], set()).add(route[-1])
    by_goals: dict[frozenset, list[int]] = {}
    for start, goals in goals_of.items():
        by_goals.setdefault(frozenset(goals), []).append(start)
    folded, alone = [], {}
    for goals, starts in by_goals.items():
        if len(starts) > 1:
            folded.append((tuple(starts), tuple(sorted(goals))))
        else:
            alone.setdefault(goals | {starts[0]}, []).append(starts[0])
    for members, starts in alone.items():
        folded.append((tuple(starts), tuple(sorted(members if len(starts) > 1
                                                   else members - {starts[0]}))))
    return list(spec.groups) + folded


def wall_grid(
    walls: np.ndarray, valid: np.ndarray, lo: np.ndarray, hi: np.ndarray, reach: float,
    cell_size: float,
) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """For every cell of a grid over ``[lo, hi]``, the walls closer than ``reach`` to any point of
    the cell. Padding entries point at the last wall slot, which must be masked if unused.

    Returns ``(cell_walls [C, Kw], origin [2], (nx, ny))``.
    """
    nx = max(1, int(np.ceil((hi[0] - lo[0]) / cell_size)))
    ny = max(1, int(np.ceil((hi[1] - lo[1]) / cell_size)))
    iy, ix = np.mgrid[0:ny, 0:nx]
    centre = np.stack([lo[0] + (ix.ravel() + 0.5) * cell_size,
                       lo[1] + (iy.ravel() + 0.5) * cell_size], axis=-1)  # [C, 2]
    radius = reach + cell_size * np.sqrt(0.5)
    # the candidate (cell, wall) pairs of a segment grid, then their exact distances: the cost
    # grows with the walls near each cell, not cells x walls (GDC3: 12 s -> well under 1 s)
    kept = np.flatnonzero(valid)
    grid = SegmentGrid(walls[kept], cell_size)
    cells, near = [], []
    for c, w in grid.near_points(centre, radius):
        close = pair_distances(centre[c], grid.segments[w]) <= radius
        cells.append(c[close])
        near.append(kept[w[close]])
    cell, wall = unique_pairs(np.concatenate([np.zeros(0, np.int64), *cells]),
                              np.concatenate([np.zeros(0, np.int64), *near]))
    counts = np.bincount(cell, minlength=len(centre))
    width = max(1, int(counts.max()))
    cell_walls = np.full((len(centre), width), walls.shape[0] - 1, dtype=np.int32)
    slot = np.arange(len(cell)) - np.repeat(np.cumsum(counts) - counts, counts)
    cell_walls[cell, slot] = wall  # each cell's walls in ascending order
    return cell_walls, lo, (nx, ny)


ZONE_WALL_MARGIN = 0.01  # m: walls this close outside a zone's rectangle still bound it


def _clip_to_rect(wall: np.ndarray, rect: np.ndarray) -> np.ndarray | None:
    """The part of segment ``(x1, y1, x2, y2)`` inside ``rect`` (Liang-Barsky), or None."""
    x1, y1, x2, y2 = wall
    dx, dy = x2 - x1, y2 - y1
    lo, hi = 0.0, 1.0
    for p, q in ((-dx, x1 - rect[0]), (dx, rect[2] - x1), (-dy, y1 - rect[1]), (dy, rect[3] - y1)):
        if abs(p) < 1e-12:
            if q < 0.0:
                return None
            continue
        t = q / p
        if p < 0.0:
            lo = max(lo, t)
        else:
            hi = min(hi, t)
    if lo > hi:
        return None
    return np.asarray([x1 + lo * dx, y1 + lo * dy, x1 + hi * dx, y1 + hi * dy])


def _segment_gap(a: np.ndarray, b: np.ndarray) -> float:
    """Distance (m) between segments ``a`` and ``b`` ``(x1, y1, x2, y2)``; 0 when they meet."""
    if segments_intersect(tuple(a[:2]), tuple(a[2:]), tuple(b[:2]), tuple(b[2:])):
        return 0.0
    return float(min(point_segment_distances(np.stack([a[:2], a[2:]]), b[None]).min(),
                     point_segment_distances(np.stack([b[:2], b[2:]]), a[None]).min()))


def zone_widths(spec: MapSpec) -> np.ndarray:
    """``[Z]`` free width (m) of the passage each conflict zone guards: the smallest distance
    between two separate obstacles inside the zone's rectangle (grown by ``ZONE_WALL_MARGIN``),
    an obstacle being the wall pieces there that meet one another (a jamb, a corner, the
    roundabout's island); the rectangle's shorter side when fewer than two obstacles are there
    (open space). The doorway's door gives 1 m, the hallway's corridor 1 m, the intersection's
    roads 4 m, the roundabout's ring 2.1 m."""
    widths = []
    for zone in spec.zones:
        rect = np.asarray(zone.rect, float) + ZONE_WALL_MARGIN * np.asarray([-1, -1, 1, 1])
        pieces = [c for w in spec.walls if (c := _clip_to_rect(np.asarray(w, float), rect))
                  is not None and np.hypot(c[2] - c[0], c[3] - c[1]) > 1e-6]
        gap = np.asarray([[_segment_gap(a, b) for b in pieces] for a in pieces]).reshape(
            len(pieces), len(pieces))
        # Pieces that touch belong to one obstacle (scipy's connected components).
        _, obstacle = connected_components(csr_matrix(gap < 1e-6), directed=False)
        apart = obstacle[:, None] != obstacle[None, :]
        best = gap[apart].min() if apart.any() else np.inf
        side = min(zone.rect[2] - zone.rect[0], zone.rect[3] - zone.rect[1])
        widths.append(best if np.isfinite(best) else side)
    return np.asarray(widths, float)


def compile_map(spec: MapSpec, reach: float = 2.5, cell_size: float = 1.0) -> MapArrays:
    """Compile a :class:`MapSpec` into :class:`MapArrays` (float32 / int32).

    ``reach`` (m) is how far from a point the local planner looks for walls (its longest arc plus
    the largest inflated robot radius); it sizes the per-cell wall lists.
    """
    # One masked padding wall far away at the end: wall lists point at it for their empty slots.
    walls = np.concatenate([spec.walls, [[FAR, FAR, FAR + 1.0, FAR]]], axis=0)
    valid = np.arange(walls.shape[0]) < spec.walls.shape[0]
    points = np.concatenate([spec.walls[:, :2], spec.walls[:, 2:], spec.node_positions], axis=0)
    lo = np.minimum(points.min(axis=0), spec.bounds[:2]) - reach
    hi = np.maximum(points.max(axis=0), spec.bounds[2:]) + reach
    cell_walls, origin, grid_shape = wall_grid(walls, valid, lo, hi, reach, cell_size)
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
        cell_walls=jnp.asarray(cell_walls, jnp.int32),
        grid_origin=jnp.asarray(origin, f32),
        zone_rect=jnp.asarray(np.reshape([z.rect for z in spec.zones], (-1, 4)), f32),
        zone_width=jnp.asarray(zone_widths(spec), f32),
        max_route_nodes=longest,
        grid_shape=grid_shape,
        cell_size=float(cell_size),
        reach=float(reach),
    )
