"""Every problem of a map in one pass: the loader's errors, and warnings for what loads but is
probably wrong.

``check_map(data)`` returns :class:`MapProblem` items, errors first in file order, then warnings.
Errors are :func:`sgjax.maps.schema.parse_map_collecting`'s (what ``sgjax.maps.load`` refuses);
warnings are computed on the map made of the valid elements:

- ``nodes outside the bounds``: a node the drawing (and ``sgjax maps show``) crops away;
- ``nodes outside every enclosed region``: on a map with walls, the nodes from which a
  robot-sized disc can roll off the map without touching a wall (one warning naming them: a
  spawn outside the building, or a building with a gap in its walls);
- ``zones that no route crosses``: a conflict zone that no robot's shortest path enters;
- ``open wall ends near the graph``: a wall end that stops less than 0.5 m short of another
  wall (too narrow a gap for a robot: a corner that does not close), within 1.5 m of a node or
  an edge;
- ``equal-length route ties``: (start, goal) pairs of a group or route with two different
  shortest paths; robots always take the same one.

Used by ``sgjax maps check FILE...`` and by the editor (``sgjax edit``), which shows each problem
at its ``point``.
"""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from sgjax.maps.arrays import spawn_groups
from sgjax.maps.routing import NO_PATH, all_pairs_shortest_paths, path_nodes
from sgjax.maps.schema import (
    DEFAULT_CLEARANCE,
    MapSpec,
    parse_map_collecting,
)
from sgjax.maps.segment_grid import SegmentGrid, bounded_runs, points_along

SEVERITIES = ("error", "warning")
# JSON list key -> the element kind the editor highlights
ELEMENT_KINDS = {"walls": "wall", "nodes": "node", "edges": "edge", "groups": "group",
                 "routes": "route", "zones": "zone", "pedestrian_groups": "pedestrian_group",
                 "bounds": "bounds"}
OPEN_END_REACH = 1.5  # m: an open wall end this close to the graph is reported
NEAR_MISS = 0.5  # m: a wall end this close to another wall (and not on it) was meant to meet it
JOINED = 0.05  # m: wall ends closer than this to another wall are joined to it (hand-drawn
# maps miss by a centimetre or two: SocialGym 2.0's door, hallway, intersection)
TIE_TOLERANCE = 1e-6  # relative: paths this close in length are equally short
TIE_ANGLE = 1e-3  # rad: predecessors arriving from directions this close are one path
MAX_TIE_EXAMPLES = 3
GRID_CELL = 0.5  # m: the cells of the open-end searches' segment grids
RASTER_CHUNK = 1 << 21  # wall points rasterised at once by the enclosure check


@dataclasses.dataclass(frozen=True)
class MapProblem:
    """One problem of a map: ``severity`` ("error" or "warning"), the file, the JSON path
    (``$.walls[3]``), the message, and where on the map it is (world metres) when it has a
    place."""

    severity: str
    source: str
    path: str
    message: str
    point: tuple[float, float] | None = None

    @property
    def element(self) -> tuple[str, int | None]:
        """The element the path names: ``("wall", 3)`` for ``$.walls[3]...``, ``("map", None)``
        for the top level."""
        match = re.match(r"\$\.(\w+)(?:\[(\d+)\])?", self.path)
        if not match or match.group(1) not in ELEMENT_KINDS:
            return "map", None
        index = match.group(2)
        return ELEMENT_KINDS[match.group(1)], None if index is None else int(index)

    def as_dict(self) -> dict[str, Any]:
        kind, index = self.element
        return {"severity": self.severity, "path": self.path, "message": self.message,
                "element": {"kind": kind, "index": index},
                "point": None if self.point is None else [float(v) for v in self.point]}

    def __str__(self) -> str:
        return f"{self.source}: {self.severity}: {self.path}: {self.message}"


def check_file(path: str | Path, clearance: float = DEFAULT_CLEARANCE) -> list[MapProblem]:
    """:func:`check_map` of a JSON map file (invalid JSON is one error with line and column)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as err:
        return [MapProblem("error", str(path), f"line {err.lineno} column {err.colno}",
                           f"invalid JSON: {err.msg}")]
    return check_map(data, str(path), clearance)


def check_map(data: Any, source: str = "<memory>",
              clearance: float = DEFAULT_CLEARANCE) -> list[MapProblem]:
    """Every error and warning of a decoded JSON map (``clearance``: the largest robot radius,
    m)."""
    spec, errors = parse_map_collecting(data, source, clearance)
    problems = [MapProblem("error", e.source, e.path, e.problem, _point_of(data, e.path))
                for e in errors]
    if spec is not None:
        problems += map_warnings(spec, clearance)
    return problems


def map_warnings(spec: MapSpec, clearance: float = DEFAULT_CLEARANCE) -> list[MapProblem]:
    """The warnings of a parsed map (see the module docstring)."""
    found: list[MapProblem] = []
    found += _outside_bounds(spec)
    found += _not_enclosed(spec, clearance)
    if spec.num_nodes:  # shortest paths once (Floyd-Warshall), for zones and ties
        length, next_hop = all_pairs_shortest_paths(spec.node_positions, spec.edges)
        if spec.zones:
            found += _zones_uncrossed(spec, _pair_paths(spec, next_hop))
    found += _open_wall_ends(spec)
    if spec.num_nodes and len(spec.edges):
        found += _ties(spec, length)
    return found


def _point_of(data: Any, path: str) -> tuple[float, float] | None:
    """Where the element at ``path`` is drawn (a node's position, a wall's or an edge's middle,
    a zone's centre, a group's first start, a route's start), when the data says."""
    match = re.match(r"\$\.(\w+)\[(\d+)\]", path)
    if not match or not isinstance(data, dict):
        return None
    items = data.get(match.group(1))
    index = int(match.group(2))
    if not isinstance(items, list) or index >= len(items):
        return None
    item = items[index]
    try:
        if match.group(1) == "nodes":
            x, y = item["position"]
            return float(x), float(y)
        if match.group(1) == "walls":
            return (float(item[0]) + float(item[2])) / 2, (float(item[1]) + float(item[3])) / 2
        if match.group(1) == "zones":
            r = item["rect"]
            return (float(r[0]) + float(r[2])) / 2, (float(r[1]) + float(r[3])) / 2
        if match.group(1) in ("groups", "pedestrian_groups", "routes"):
            first = item["starts"][0] if match.group(1) != "routes" else item[0]
            x, y = next(n["position"] for n in data["nodes"] if n["id"] == first)
            return float(x), float(y)
        if match.group(1) == "edges":
            where = {n["id"]: n["position"] for n in data["nodes"]}
            (ax, ay), (bx, by) = where[item[0]], where[item[1]]
            return (float(ax) + float(bx)) / 2, (float(ay) + float(by)) / 2
    except (KeyError, TypeError, ValueError, IndexError, StopIteration):
        return None
    return None


def _node_problem(spec: MapSpec, row: int, message: str) -> MapProblem:
    x, y = spec.node_positions[row]
    return MapProblem("warning", spec.source, f"$.nodes[{row}]", message, (float(x), float(y)))


def _outside_bounds(spec: MapSpec) -> list[MapProblem]:
    xmin, ymin, xmax, ymax = spec.bounds
    out = []
    for row, (x, y) in enumerate(spec.node_positions):
        if not (xmin <= x <= xmax and ymin <= y <= ymax):
            out.append(_node_problem(
                spec, row, f"node {spec.node_ids[row]} at ({x:.2f}, {y:.2f}) is outside the "
                f"bounds [{xmin:g}, {ymin:g}, {xmax:g}, {ymax:g}]: drawings crop it away"))
    return out


def _not_enclosed(spec: MapSpec, clearance: float) -> list[MapProblem]:
    """Nodes from which a disc of about ``clearance`` radius reaches the outside of the
    drawing without touching a wall (on a map with walls; one warning for them all)."""
    if len(spec.walls) == 0 or spec.num_nodes == 0:
        return []
    points = np.concatenate([spec.node_positions, spec.walls[:, :2], spec.walls[:, 2:]])
    low = np.minimum(points.min(0), spec.bounds[:2]) - 2.0
    high = np.maximum(points.max(0), spec.bounds[2:]) + 2.0
    cell = max(0.05, float(np.max(high - low)) / 1500)
    shape = tuple(np.ceil((high - low) / cell).astype(int) + 1)
    wall_cells = np.zeros(shape, bool)
    # the cells each wall passes through, sampled at cell / 2, walls in bounded batches
    counts = np.ceil(np.hypot(*(spec.walls[:, 2:] - spec.walls[:, :2]).T) / (cell / 2)) + 1
    for first, last in bounded_runs(counts, RASTER_CHUNK):
        _, points = points_along(spec.walls[first:last], counts[first:last])
        cells = np.round((points - low) / cell).astype(int)
        wall_cells[cells[:, 0], cells[:, 1]] = True
    # cells whose centre is within about 0.9 clearance of a wall (to a cell's accuracy)
    near = ndimage.distance_transform_edt(~wall_cells) * cell < 0.9 * clearance
    regions, _ = ndimage.label(~near)
    border = np.unique(np.concatenate([regions[0], regions[-1], regions[:, 0], regions[:, -1]]))
    cells = np.clip(np.round((spec.node_positions - low) / cell).astype(int), 0,
                    np.asarray(shape) - 1)
    outside = np.isin(regions[cells[:, 0], cells[:, 1]], border[border > 0])
    if not outside.any():
        return []
    rows = np.flatnonzero(outside)
    named = ", ".join(str(spec.node_ids[r]) for r in rows[:MAX_TIE_EXAMPLES])
    more = " ..." if len(rows) > MAX_TIE_EXAMPLES else ""
    return [_node_problem(spec, int(rows[0]), f"{len(rows)} of {spec.num_nodes} node(s) "
                          f"({named}{more}) are enclosed by no walls: a robot there can drive "
                          "off the map (a gap in the walls?)")]


def _pair_paths(spec: MapSpec, next_hop: np.ndarray) -> list[tuple[int, int, np.ndarray]]:
    """The robots' (start row, goal row, path points [P, 2]) of every allowed pair
    (``next_hop``: :func:`all_pairs_shortest_paths`'s)."""
    pairs = {(s, g) for starts, goals in spawn_groups(spec) for s in starts for g in goals
             if s != g and next_hop[s, g] != NO_PATH}
    return [(s, g, spec.node_positions[path_nodes(next_hop, s, g)]) for s, g in sorted(pairs)]


def _crosses_rect(points: np.ndarray, rect: tuple[float, float, float, float]) -> bool:
    """Whether the polyline ``points [P, 2]`` enters the rectangle (sampled every 5 cm)."""
    a, b = points[:-1], points[1:]
    steps = np.maximum(np.ceil(np.linalg.norm(b - a, axis=1) / 0.05), 1).astype(int)
    samples = np.concatenate([a[i] + np.linspace(0, 1, n + 1)[:, None] * (b[i] - a[i])
                              for i, n in enumerate(steps)] or [points])
    inside = ((samples[:, 0] >= rect[0]) & (samples[:, 0] <= rect[2])
              & (samples[:, 1] >= rect[1]) & (samples[:, 1] <= rect[3]))
    return bool(inside.any())


def _zones_uncrossed(spec: MapSpec, paths: list) -> list[MapProblem]:
    out = []
    for i, zone in enumerate(spec.zones):
        if not any(_crosses_rect(points, zone.rect) for _, _, points in paths):
            x0, y0, x1, y1 = zone.rect
            out.append(MapProblem("warning", spec.source, f"$.zones[{i}]",
                                  f"zone {zone.name!r}: no robot's shortest route crosses it "
                                  f"(of {len(paths)} start-goal pairs)",
                                  ((x0 + x1) / 2, (y0 + y1) / 2)))
    return out


def _open_wall_ends(spec: MapSpec) -> list[MapProblem]:
    """Wall ends that stop short of another wall (closer than :data:`NEAR_MISS`, joined to
    none) within :data:`OPEN_END_REACH` of a node or an edge: a corner that does not close. A
    door, a gap a robot passes, is wider and is not reported. Both searches go through
    :class:`SegmentGrid`: the work grows with the walls near each end."""
    walls = spec.walls
    if len(walls) < 2 or spec.num_nodes == 0:
        return []
    pos = spec.node_positions
    graph = np.concatenate([pos[:, [0, 1, 0, 1]],
                            np.concatenate([pos[spec.edges[:, 0]], pos[spec.edges[:, 1]]], 1)])
    ends = np.concatenate([walls[:, :2], walls[:, 2:]])  # [2W, 2]: end k of wall k % W
    reach = SegmentGrid(graph, GRID_CELL).nearest(ends, OPEN_END_REACH)[0]
    near_graph = np.flatnonzero(reach < OPEN_END_REACH)
    gap, nearest = SegmentGrid(walls, GRID_CELL).nearest(ends[near_graph], NEAR_MISS,
                                                         skip=near_graph % len(walls))
    out = []
    for row in np.flatnonzero((gap >= JOINED) & (gap < NEAR_MISS)):
        k = near_graph[row]
        end = ends[k]
        out.append(MapProblem(
            "warning", spec.source, f"$.walls[{k % len(walls)}]",
            f"wall end at ({end[0]:.2f}, {end[1]:.2f}) stops {gap[row]:.2f} m short of wall "
            f"$.walls[{nearest[row]}], {reach[k]:.2f} m from the navigation graph: a corner "
            "that does not close?", (float(end[0]), float(end[1]))))
    return sorted(out, key=lambda problem: int(problem.path[8:-1]))


def tied_goals(spec: MapSpec, start: int, length: np.ndarray) -> np.ndarray:
    """``[N]`` bool: nodes reached from ``start`` by two different shortest paths (arriving
    from different directions somewhere along them)."""
    pos, d = spec.node_positions, length[start]
    tail = np.concatenate([spec.edges[:, 0], spec.edges[:, 1]])  # directed edges u -> x
    head = np.concatenate([spec.edges[:, 1], spec.edges[:, 0]])
    step = pos[head] - pos[tail]
    with np.errstate(invalid="ignore"):  # inf - inf between unreachable nodes: not tight
        tight = np.abs(d[tail] + np.linalg.norm(step, axis=1) - d[head]) <= (
            TIE_TOLERANCE * np.maximum(d[head], 1.0))
    angle = np.arctan2(step[:, 1], step[:, 0])
    tied = np.zeros(spec.num_nodes, bool)
    for v in np.argsort(d):
        if not np.isfinite(d[v]) or v == start:
            continue
        into = np.flatnonzero(tight & (head == v))
        spread = np.abs(np.angle(np.exp(1j * (angle[into][:, None] - angle[into][None]))))
        tied[v] = bool(tied[tail[into]].any()) or (len(into) > 1 and spread.max() > TIE_ANGLE)
    return tied


def _ties(spec: MapSpec, length: np.ndarray) -> list[MapProblem]:
    """Groups and routes with tied pairs (``length [N, N]``: shortest path lengths, m)."""
    tied_from: dict[int, np.ndarray] = {}
    out = []
    for field, items in (("groups", [(g[0], g[1]) for g in spec.groups]),
                         ("routes", [((r[0],), (r[-1],)) for r in spec.routes])):
        for i, (starts, goals) in enumerate(items):
            ties = []
            for s in starts:
                if s not in tied_from:
                    tied_from[s] = tied_goals(spec, s, length)
                ties += [(s, g) for g in goals if g != s and tied_from[s][g]]
            if ties:
                ids = spec.node_ids
                examples = ", ".join(f"{ids[s]} -> {ids[g]}" for s, g in ties[:MAX_TIE_EXAMPLES])
                pairs = sum(1 for s in starts for g in goals if s != g)
                x, y = spec.node_positions[ties[0][1]]
                out.append(MapProblem(
                    "warning", spec.source, f"$.{field}[{i}]",
                    f"{len(ties)} of {pairs} start-goal pair(s) have two equally short, "
                    f"different paths (e.g. {examples}); robots always take the same one",
                    (float(x), float(y))))
    return out
