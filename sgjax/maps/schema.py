"""The sgjax JSON map format, its parser and its validator.

A map file is one JSON object (metres, world frame, y up)::

    {
      "name": "doorway",                      # str, required
      "description": "...",                   # str, required
      "bounds": [xmin, ymin, xmax, ymax],     # drawing / sampling extent, required
      "walls": [[x1, y1, x2, y2], ...],       # line segments, required (may be empty)
      "nodes": [{"id": 0, "position": [x, y]}, ...],   # navigation graph nodes, required
      "edges": [[id_a, id_b], ...],           # undirected, required
      "groups": [{"starts": [ids], "goals": [ids]}],   # spawn/goal groups (optional)
      "routes": [[start_id, ..., goal_id], ...],        # explicit routes (optional)
      "zones": [{"name": "door", "rect": [xmin, ymin, xmax, ymax]}]  # conflict zones (optional)
    }

At least one of ``groups`` and ``routes`` must be given. A group allows every (start, goal) pair
with start != goal; a route ``[start, waypoint, ..., goal]`` allows its (first, last) pair, whose
nodes must be joined by some path in the graph. Robots always drive the shortest graph path between
their start and goal (as SocialGym 2.0's A* did with its scenario paths); a route's interior
waypoints need not follow edges and are kept as written (``to_json`` gives them back) but not
driven: sgjax pedestrians walk graph paths between nodes (``docs/humans.md``).

Every problem is reported as a :class:`MapError` naming the file, the JSON path and the problem.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from sgjax.kernels.geometry import segments_intersect_pairs
from sgjax.maps.segment_grid import SegmentGrid, pair_distances
from sgjax.maps.size_limits import (
    DENSITY_CELL,
    MAX_WALLS_PER_CELL,
    density_problem,
    oversized_lists,
)
from sgjax.validation import suggest

TOP_LEVEL_REQUIRED = ("name", "description", "bounds", "walls", "nodes", "edges")
TOP_LEVEL_OPTIONAL = ("groups", "routes", "zones", "pedestrian_groups")
DEFAULT_CLEARANCE = 0.25  # m: default robot radius every node must keep from every wall
MAX_COORDINATE = 1e5  # m: float32 resolves 1 cm up to about 1.3e5 m


class MapError(ValueError):
    """A malformed or inconsistent map file: ``source`` (the file), ``path`` (the JSON path,
    ``$.walls[3]``), ``problem``; ``errors`` holds every error found in the same pass (this one
    first)."""

    def __init__(self, source: str, path: str, problem: str):
        self.source, self.path, self.problem = source, path, problem
        self.errors: tuple[MapError, ...] = (self,)
        super().__init__(f"{source}: {path}: {problem}")


@dataclasses.dataclass(frozen=True)
class Zone:
    name: str
    rect: tuple[float, float, float, float]  # xmin, ymin, xmax, ymax (m)


@dataclasses.dataclass(frozen=True)
class MapSpec:
    """A validated map, host side (numpy). ``walls`` is ``[W, 4]`` of ``(x1, y1, x2, y2)``."""

    name: str
    description: str
    bounds: tuple[float, float, float, float]
    walls: np.ndarray  # [W, 4] float
    node_ids: np.ndarray  # [N] int: the file's ids; row i of node_positions belongs to node_ids[i]
    node_positions: np.ndarray  # [N, 2] float
    edges: np.ndarray  # [E, 2] int, row indices into node_positions
    groups: tuple[tuple[tuple[int, ...], tuple[int, ...]], ...]  # (starts, goals) as row indices
    routes: tuple[tuple[int, ...], ...]  # explicit routes as row indices
    zones: tuple[Zone, ...]
    source: str = "<memory>"
    # (starts, goals) as row indices for pedestrians walking routes (human_goals="routes"); the
    # robots' groups when empty
    pedestrian_groups: tuple[tuple[tuple[int, ...], tuple[int, ...]], ...] = ()

    @property
    def num_nodes(self) -> int:
        return int(self.node_positions.shape[0])

    def index_of(self, node_id: int) -> int:
        """Row index of the node with file id ``node_id``."""
        return int(np.flatnonzero(self.node_ids == node_id)[0])

    def to_json(self) -> dict:
        """The map in the JSON format (``parse_map(spec.to_json())`` gives it back)."""
        ids = [int(i) for i in self.node_ids]
        data: dict[str, Any] = {
            "name": self.name,
            "description": self.description,
            "bounds": list(self.bounds),
            "walls": self.walls.tolist(),
            "nodes": [{"id": i, "position": p.tolist()} for i, p in zip(ids, self.node_positions,
                                                                         strict=True)],
            "edges": [[ids[a], ids[b]] for a, b in self.edges],
        }
        if self.groups:
            data["groups"] = [{"starts": [ids[n] for n in starts], "goals": [ids[n] for n in goals]}
                              for starts, goals in self.groups]
        if self.routes:
            data["routes"] = [[ids[n] for n in route] for route in self.routes]
        if self.zones:
            data["zones"] = [{"name": z.name, "rect": list(z.rect)} for z in self.zones]
        if self.pedestrian_groups:
            data["pedestrian_groups"] = [
                {"starts": [ids[n] for n in starts], "goals": [ids[n] for n in goals]}
                for starts, goals in self.pedestrian_groups]
        return data


def _type_name(value: Any) -> str:
    return type(value).__name__


def _expect_number(source: str, path: str, value: Any) -> float:
    """A coordinate (m): a finite number within :data:`MAX_COORDINATE` of the origin."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise MapError(source, path, f"expected a number, got {_type_name(value)} {value!r}")
    return checked_coordinate(source, path, value)


def checked_coordinate(source: str, path: str, value: float) -> float:
    """``value`` (m) as a float if it is finite and within :data:`MAX_COORDINATE` of the
    origin, else a :class:`MapError` at ``source``, ``path`` (also used by the SocialGym 2.0
    readers, whose numbers may come as strings)."""
    if not math.isfinite(value):
        raise MapError(source, path, f"expected a finite number, got {value!r}")
    if abs(value) > MAX_COORDINATE:
        raise MapError(source, path, f"{value!r} m is beyond +-{MAX_COORDINATE:g} m: the "
                                     "simulator computes in float32, whose steps there exceed "
                                     "a centimetre")
    return float(value)


def _expect_int(source: str, path: str, value: Any) -> int:
    """An integer (a node id or a reference to one) that fits the int64 arrays ids live in."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise MapError(source, path, f"expected an integer, got {_type_name(value)} {value!r}")
    if not -2**63 <= value < 2**63:
        raise MapError(source, path, f"{value} is beyond the 64-bit integer range of node ids")
    return int(value)


def _expect_list(source: str, path: str, value: Any, length: int | None = None) -> list:
    if not isinstance(value, list):
        raise MapError(source, path, f"expected a list, got {_type_name(value)}")
    if length is not None and len(value) != length:
        raise MapError(source, path, f"expected a list of {length} items, got {len(value)}")
    return value


def _unknown_key(source: str, path: str, key: Any, valid: tuple[str, ...]) -> MapError:
    return MapError(source, f"{path}.{key}", f"unknown key{suggest(str(key), valid)}; valid "
                                             f"keys are: {', '.join(valid)}")


def _expect_keys(
    source: str, path: str, obj: Any, required: tuple[str, ...], optional: tuple[str, ...] = ()
) -> dict:
    if not isinstance(obj, dict):
        raise MapError(source, path, f"expected an object, got {_type_name(obj)}")
    for key in obj:
        if key not in required and key not in optional:
            raise _unknown_key(source, path, key, required + optional)
    for key in required:
        if key not in obj:
            raise MapError(source, path, f"missing required key {key!r}")
    return obj


class _Collector:
    """The errors found so far; parsing goes on past a bad element (skipping it) so that one
    pass reports every error."""

    def __init__(self, source: str):
        self.source = source
        self.errors: list[MapError] = []

    def add(self, error: MapError) -> None:
        self.errors.append(error)

    @contextlib.contextmanager
    def element(self) -> Iterator[None]:
        """Record a ``MapError`` raised inside instead of letting it out."""
        try:
            yield
        except MapError as error:
            self.errors.append(error)


def _combined(errors: list[MapError]) -> MapError:
    """The first error, its message followed by the others', every one in ``.errors``."""
    first = errors[0]
    if len(errors) == 1:
        return first
    rest = "".join(f"\n  {e.path}: {e.problem}" for e in errors[1:])
    combined = MapError(first.source, first.path,
                        f"{first.problem}\n  and {len(errors) - 1} more error(s):{rest}")
    combined.problem, combined.errors = first.problem, tuple(errors)
    return combined


def parse_map(data: Any, source: str = "<memory>", clearance: float = DEFAULT_CLEARANCE) -> MapSpec:
    """Validate a decoded JSON map and return a :class:`MapSpec`.

    ``clearance`` (m) is the largest robot radius the map must accommodate: every node must keep at
    least this distance from every wall. Raises :class:`MapError` for the first error in file
    order, its message listing every other one too (``.errors`` holds them all).
    """
    spec, errors = parse_map_collecting(data, source, clearance)
    if errors:
        raise _combined(errors)
    assert spec is not None
    return spec


def parse_map_collecting(data: Any, source: str = "<memory>",
                         clearance: float = DEFAULT_CLEARANCE
                         ) -> tuple[MapSpec | None, list[MapError]]:
    """Every error of a decoded JSON map in one pass, and the map made of its valid elements
    (None when the top level is not an object): ``(spec, errors)``. Elements with an error are
    left out of ``spec``; references to them are errors of their own."""
    found = _Collector(source)
    if not isinstance(data, dict):
        found.add(MapError(source, "$", f"expected an object, got {_type_name(data)}"))
        return None, found.errors
    oversized = oversized_lists(data)
    if oversized:  # refused before any other work (sgjax.maps.size_limits)
        return None, [MapError(source, path, problem) for path, problem in oversized]
    valid = TOP_LEVEL_REQUIRED + TOP_LEVEL_OPTIONAL
    for key in data:
        if key not in valid:
            found.add(_unknown_key(source, "$", key, valid))
    for key in TOP_LEVEL_REQUIRED:
        if key not in data:
            found.add(MapError(source, "$", f"missing required key {key!r}"))
    name = data.get("name", "")
    if "name" in data and (not isinstance(name, str) or not name):
        found.add(MapError(source, "$.name", "expected a non-empty string"))
        name = ""
    description = data.get("description", "")
    if not isinstance(description, str):
        found.add(MapError(source, "$.description",
                           f"expected a string, got {_type_name(description)}"))
        description = ""
    bounds: tuple[float, ...] = (-1.0, -1.0, 1.0, 1.0)
    if "bounds" in data:
        with found.element():
            raw = _expect_list(source, "$.bounds", data["bounds"], 4)
            parsed = tuple(_expect_number(source, f"$.bounds[{i}]", v) for i, v in enumerate(raw))
            if not (parsed[0] < parsed[2] and parsed[1] < parsed[3]):
                raise MapError(source, "$.bounds", "expected xmin < xmax and ymin < ymax")
            bounds = parsed

    walls = _parse_walls(found, data.get("walls", []))
    grid = SegmentGrid(walls, DENSITY_CELL)
    most, centre = grid.most_in_one_cell()
    if most > MAX_WALLS_PER_CELL:  # refused before the checks that look near every wall
        found.add(MapError(source, "$.walls", density_problem(most, centre, grid.cell)))
        return None, found.errors
    node_ids, positions = _parse_nodes(found, data.get("nodes", []), "nodes" in data)
    index = {int(node_id): i for i, node_id in enumerate(node_ids)}
    edges = _parse_edges(found, data.get("edges", []), index)
    _check_clearance(found, grid, node_ids, positions, clearance)
    edges = _check_edges_clear_walls(found, grid, edges, positions, node_ids)

    if "groups" not in data and "routes" not in data:
        found.add(MapError(source, "$", "a map needs 'groups' or 'routes' to place robots"))
    groups = _parse_groups(found, data.get("groups", []), index)
    routes = _parse_routes(found, data.get("routes", []), index)
    zones = _parse_zones(found, data.get("zones", []))
    pedestrian_groups = _parse_groups(found, data.get("pedestrian_groups", []), index,
                                      "pedestrian_groups")
    spec = MapSpec(
        name=name,
        description=description,
        bounds=bounds,  # type: ignore[arg-type]
        walls=walls,
        node_ids=node_ids,
        node_positions=positions,
        edges=edges,
        groups=groups,
        routes=routes,
        zones=zones,
        source=source,
        pedestrian_groups=pedestrian_groups,
    )
    _check_connected_pairs(found, spec)
    return spec, found.errors


def _parse_walls(found: _Collector, raw: Any) -> np.ndarray:
    source, walls = found.source, []
    with found.element():
        raw = _expect_list(source, "$.walls", raw)
        for i, wall in enumerate(raw):
            with found.element():
                path = f"$.walls[{i}]"
                coords = [_expect_number(source, f"{path}[{k}]", v) for k, v in enumerate(
                    _expect_list(source, path, wall, 4))]
                if math.hypot(coords[2] - coords[0], coords[3] - coords[1]) < 1e-6:
                    raise MapError(source, path, f"zero-length wall at ({coords[0]}, {coords[1]})")
                walls.append(coords)
    return np.asarray(walls, dtype=np.float64).reshape(-1, 4)


def _parse_nodes(found: _Collector, raw: Any, given: bool) -> tuple[np.ndarray, np.ndarray]:
    source = found.source
    ids: list[int] = []
    seen: set[int] = set()
    positions: list[list[float]] = []
    with found.element():
        nodes = _expect_list(source, "$.nodes", raw)
        if given and not nodes:
            raise MapError(source, "$.nodes", "a map needs at least one navigation node")
        for i, node in enumerate(nodes):
            with found.element():
                path = f"$.nodes[{i}]"
                _expect_keys(source, path, node, ("id", "position"))
                node_id = _expect_int(source, f"{path}.id", node["id"])
                if node_id in seen:
                    raise MapError(source, f"{path}.id", f"duplicate node id {node_id}")
                seen.add(node_id)
                pos = _expect_list(source, f"{path}.position", node["position"], 2)
                positions.append([_expect_number(source, f"{path}.position[{k}]", v)
                                  for k, v in enumerate(pos)])
                ids.append(node_id)
    return np.asarray(ids, dtype=np.int64), np.asarray(positions, dtype=np.float64).reshape(-1, 2)


def _node_row(source: str, path: str, value: Any, index: dict[int, int]) -> int:
    node_id = _expect_int(source, path, value)
    if node_id not in index:
        raise MapError(source, path, f"refers to node id {node_id}, which does not exist")
    return index[node_id]


def _parse_edges(found: _Collector, raw: Any, index: dict[int, int]) -> np.ndarray:
    source, edges = found.source, []
    with found.element():
        for i, edge in enumerate(_expect_list(source, "$.edges", raw)):
            with found.element():
                path = f"$.edges[{i}]"
                pair = _expect_list(source, path, edge, 2)
                a = _node_row(source, f"{path}[0]", pair[0], index)
                b = _node_row(source, f"{path}[1]", pair[1], index)
                if a == b:
                    raise MapError(source, path, f"edge joins node {pair[0]} to itself")
                edges.append((i, a, b))
    return np.asarray(edges, dtype=np.int64).reshape(-1, 3)


def point_segment_distances(points: np.ndarray, walls: np.ndarray) -> np.ndarray:
    """Host-side distances (m) from ``points [P, 2]`` to segments ``walls [W, 4]``: ``[P, W]``."""
    return pair_distances(points[:, None, :], walls[None, :, :])


def _check_clearance(found: _Collector, grid: SegmentGrid, ids: np.ndarray,
                     positions: np.ndarray, clearance: float) -> None:
    """Every node closer to a wall than ``clearance`` (m), each with its nearest wall (the
    lowest-numbered of equally near ones); ``grid``: the walls'."""
    walls = grid.segments
    if walls.shape[0] == 0 or positions.shape[0] == 0:
        return
    best, nearest = grid.nearest(positions, clearance)
    for node in np.flatnonzero(best < clearance):
        found.add(MapError(
            found.source,
            f"$.nodes[{node}]",
            f"node {ids[node]} at ({positions[node][0]:.3f}, {positions[node][1]:.3f}) is "
            f"{best[node]:.3f} m from "
            f"wall $.walls[{nearest[node]}], closer than the robot radius {clearance} m",
        ))


def _check_edges_clear_walls(found: _Collector, grid: SegmentGrid, edges: np.ndarray,
                             positions: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Every edge that crosses a wall is an error (named with the lowest-numbered wall it
    crosses); ``edges [E, 3]`` (file index, row a, row b) -> ``[E', 2]`` rows of the edges
    kept; ``grid``: the walls'."""
    walls = grid.segments
    segments = np.concatenate([positions[edges[:, 1]], positions[edges[:, 2]]], 1)
    crossed = np.full(len(edges), len(walls), np.int64)
    if len(walls):
        for edge, wall in grid.near_segments(segments):
            hit = segments_intersect_pairs(segments[edge], walls[wall])
            np.minimum.at(crossed, edge[hit], wall[hit])
    for (i, a, b), wall in zip(edges, crossed, strict=True):
        if wall < len(walls):
            found.add(MapError(found.source, f"$.edges[{i}]",
                               f"edge {ids[a]}-{ids[b]} crosses wall $.walls[{wall}]"))
    return edges[crossed == len(walls)][:, 1:].reshape(-1, 2)


def _parse_groups(found: _Collector, raw: Any, index: dict[int, int], field: str = "groups"
                  ) -> tuple:
    source, groups = found.source, []
    with found.element():
        for i, group in enumerate(_expect_list(source, f"$.{field}", raw)):
            with found.element():
                path = f"$.{field}[{i}]"
                _expect_keys(source, path, group, ("starts", "goals"))
                sides = []
                for key in ("starts", "goals"):
                    ids = _expect_list(source, f"{path}.{key}", group[key])
                    if not ids:
                        raise MapError(source, f"{path}.{key}", "expected at least one node id")
                    sides.append(tuple(_node_row(source, f"{path}.{key}[{k}]", v, index)
                                       for k, v in enumerate(ids)))
                if set(sides[0]) == set(sides[1]) and len(sides[0]) < 2:
                    raise MapError(source, path, "a group needs a goal different from its start")
                groups.append((sides[0], sides[1]))
    return tuple(groups)


def _parse_routes(found: _Collector, raw: Any, index: dict[int, int]) -> tuple:
    source, routes = found.source, []
    with found.element():
        for i, route in enumerate(_expect_list(source, "$.routes", raw)):
            with found.element():
                path = f"$.routes[{i}]"
                nodes = _expect_list(source, path, route)
                if len(nodes) < 2:
                    raise MapError(source, path, "a route needs at least a start and a goal")
                rows = tuple(_node_row(source, f"{path}[{k}]", v, index)
                             for k, v in enumerate(nodes))
                if rows[0] == rows[-1]:
                    raise MapError(source, path, "a route must end at a node other than its start")
                routes.append(rows)
    return tuple(routes)


def _parse_zones(found: _Collector, raw: Any) -> tuple:
    source, zones = found.source, []
    with found.element():
        for i, zone in enumerate(_expect_list(source, "$.zones", raw)):
            with found.element():
                path = f"$.zones[{i}]"
                _expect_keys(source, path, zone, ("name", "rect"))
                if not isinstance(zone["name"], str):
                    raise MapError(source, f"{path}.name", "expected a string")
                rect = tuple(_expect_number(source, f"{path}.rect[{k}]", v) for k, v in
                             enumerate(_expect_list(source, f"{path}.rect", zone["rect"], 4)))
                if not (rect[0] < rect[2] and rect[1] < rect[3]):
                    raise MapError(source, f"{path}.rect", "expected xmin < xmax and ymin < ymax")
                zones.append(Zone(zone["name"], rect))  # type: ignore[arg-type]
    return tuple(zones)


def _check_connected_pairs(found: _Collector, spec: MapSpec) -> None:
    """A group or route whose start cannot reach its goal (one error per group or route)."""
    from sgjax.maps.routing import connected_components

    component = connected_components(spec.num_nodes, spec.edges)
    for i, (starts, goals) in enumerate(spec.groups):
        apart = [(s, g) for s in starts for g in goals if s != g and component[s] != component[g]]
        if apart:
            s, g = apart[0]
            more = f" (and {len(apart) - 1} more pair(s))" if len(apart) > 1 else ""
            found.add(MapError(spec.source, f"$.groups[{i}]",
                               f"no path in the graph from start {spec.node_ids[s]} "
                               f"to goal {spec.node_ids[g]}{more}"))
    for i, route in enumerate(spec.routes):
        if component[route[0]] != component[route[-1]]:
            found.add(MapError(spec.source, f"$.routes[{i}]",
                               f"no path in the graph from start {spec.node_ids[route[0]]} to "
                               f"goal {spec.node_ids[route[-1]]}"))
