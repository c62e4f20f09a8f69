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

import dataclasses
import math
from typing import Any

import numpy as np

from sgjax.kernels.geometry import segments_intersect

TOP_LEVEL_REQUIRED = ("name", "description", "bounds", "walls", "nodes", "edges")
TOP_LEVEL_OPTIONAL = ("groups", "routes", "zones", "pedestrian_groups")
DEFAULT_CLEARANCE = 0.25  # m: default robot radius every node must keep from every wall


class MapError(ValueError):
    """A malformed or inconsistent map file."""

    def __init__(self, source: str, path: str, problem: str):
        self.source, self.path, self.problem = source, path, problem
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
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise MapError(source, path, f"expected a number, got {_type_name(value)} {value!r}")
    if not math.isfinite(value):
        raise MapError(source, path, f"expected a finite number, got {value!r}")
    return float(value)


def _expect_int(source: str, path: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise MapError(source, path, f"expected an integer, got {_type_name(value)} {value!r}")
    return int(value)


def _expect_list(source: str, path: str, value: Any, length: int | None = None) -> list:
    if not isinstance(value, list):
        raise MapError(source, path, f"expected a list, got {_type_name(value)}")
    if length is not None and len(value) != length:
        raise MapError(source, path, f"expected a list of {length} items, got {len(value)}")
    return value


def _expect_keys(
    source: str, path: str, obj: Any, required: tuple[str, ...], optional: tuple[str, ...] = ()
) -> dict:
    if not isinstance(obj, dict):
        raise MapError(source, path, f"expected an object, got {_type_name(obj)}")
    for key in obj:
        if key not in required and key not in optional:
            valid = ", ".join(required + optional)
            raise MapError(source, f"{path}.{key}", f"unknown key; valid keys are: {valid}")
    for key in required:
        if key not in obj:
            raise MapError(source, path, f"missing required key {key!r}")
    return obj


def parse_map(data: Any, source: str = "<memory>", clearance: float = DEFAULT_CLEARANCE) -> MapSpec:
    """Validate a decoded JSON map and return a :class:`MapSpec`.

    ``clearance`` (m) is the largest robot radius the map must accommodate: every node must keep at
    least this distance from every wall.
    """
    obj = _expect_keys(source, "$", data, TOP_LEVEL_REQUIRED, TOP_LEVEL_OPTIONAL)
    name = obj["name"]
    if not isinstance(name, str) or not name:
        raise MapError(source, "$.name", "expected a non-empty string")
    description = obj["description"]
    if not isinstance(description, str):
        raise MapError(source, "$.description", f"expected a string, got {_type_name(description)}")
    bounds_raw = _expect_list(source, "$.bounds", obj["bounds"], 4)
    bounds = tuple(_expect_number(source, f"$.bounds[{i}]", v) for i, v in enumerate(bounds_raw))
    if not (bounds[0] < bounds[2] and bounds[1] < bounds[3]):
        raise MapError(source, "$.bounds", "expected xmin < xmax and ymin < ymax")

    walls = _parse_walls(source, obj["walls"])
    node_ids, positions = _parse_nodes(source, obj["nodes"])
    index = {int(node_id): i for i, node_id in enumerate(node_ids)}
    edges = _parse_edges(source, obj["edges"], index)
    _check_clearance(source, walls, node_ids, positions, clearance)
    _check_edges_clear_walls(source, walls, edges, positions, node_ids)

    if "groups" not in obj and "routes" not in obj:
        raise MapError(source, "$", "a map needs 'groups' or 'routes' to place robots")
    groups = _parse_groups(source, obj.get("groups", []), index)
    routes = _parse_routes(source, obj.get("routes", []), index)
    zones = _parse_zones(source, obj.get("zones", []))
    pedestrian_groups = _parse_groups(source, obj.get("pedestrian_groups", []), index,
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
    _check_connected_pairs(spec)
    return spec


def _parse_walls(source: str, raw: Any) -> np.ndarray:
    walls = []
    for i, wall in enumerate(_expect_list(source, "$.walls", raw)):
        path = f"$.walls[{i}]"
        coords = [_expect_number(source, f"{path}[{k}]", v) for k, v in enumerate(
            _expect_list(source, path, wall, 4))]
        if math.hypot(coords[2] - coords[0], coords[3] - coords[1]) < 1e-6:
            raise MapError(source, path, f"zero-length wall at ({coords[0]}, {coords[1]})")
        walls.append(coords)
    return np.asarray(walls, dtype=np.float64).reshape(-1, 4)


def _parse_nodes(source: str, raw: Any) -> tuple[np.ndarray, np.ndarray]:
    nodes = _expect_list(source, "$.nodes", raw)
    if not nodes:
        raise MapError(source, "$.nodes", "a map needs at least one navigation node")
    ids, positions, seen = [], [], set()
    for i, node in enumerate(nodes):
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
    return np.asarray(ids, dtype=np.int64), np.asarray(positions, dtype=np.float64)


def _node_row(source: str, path: str, value: Any, index: dict[int, int]) -> int:
    node_id = _expect_int(source, path, value)
    if node_id not in index:
        raise MapError(source, path, f"refers to node id {node_id}, which does not exist")
    return index[node_id]


def _parse_edges(source: str, raw: Any, index: dict[int, int]) -> np.ndarray:
    edges = []
    for i, edge in enumerate(_expect_list(source, "$.edges", raw)):
        path = f"$.edges[{i}]"
        pair = _expect_list(source, path, edge, 2)
        a = _node_row(source, f"{path}[0]", pair[0], index)
        b = _node_row(source, f"{path}[1]", pair[1], index)
        if a == b:
            raise MapError(source, path, f"edge joins node {pair[0]} to itself")
        edges.append((a, b))
    return np.asarray(edges, dtype=np.int64).reshape(-1, 2)


def point_segment_distances(points: np.ndarray, walls: np.ndarray) -> np.ndarray:
    """Host-side distances (m) from ``points [P, 2]`` to segments ``walls [W, 4]``: ``[P, W]``."""
    a, b = walls[None, :, :2], walls[None, :, 2:]
    p = points[:, None, :]
    e = b - a
    t = np.clip(np.sum((p - a) * e, -1) / np.maximum(np.sum(e * e, -1), 1e-12), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * e), axis=-1)


def _check_clearance(
    source: str, walls: np.ndarray, ids: np.ndarray, positions: np.ndarray, clearance: float
) -> None:
    if walls.shape[0] == 0:
        return
    dist = point_segment_distances(positions, walls)  # [N, W]
    node, wall = np.unravel_index(np.argmin(dist), dist.shape)
    if dist[node, wall] < clearance:
        raise MapError(
            source,
            f"$.nodes[{node}]",
            f"node {ids[node]} at ({positions[node][0]:.3f}, {positions[node][1]:.3f}) is "
            f"{dist[node, wall]:.3f} m from "
            f"wall $.walls[{wall}], closer than the robot radius {clearance} m",
        )


def _check_edges_clear_walls(
    source: str, walls: np.ndarray, edges: np.ndarray, positions: np.ndarray, ids: np.ndarray
) -> None:
    for i, (a, b) in enumerate(edges):
        for w, wall in enumerate(walls):
            if segments_intersect(tuple(positions[a]), tuple(positions[b]),
                                  tuple(wall[:2]), tuple(wall[2:])):
                raise MapError(source, f"$.edges[{i}]",
                               f"edge {ids[a]}-{ids[b]} crosses wall $.walls[{w}]")


def _parse_groups(source: str, raw: Any, index: dict[int, int], field: str = "groups"
                  ) -> tuple:
    groups = []
    for i, group in enumerate(_expect_list(source, f"$.{field}", raw)):
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


def _parse_routes(source: str, raw: Any, index: dict[int, int]) -> tuple:
    routes = []
    for i, route in enumerate(_expect_list(source, "$.routes", raw)):
        path = f"$.routes[{i}]"
        nodes = _expect_list(source, path, route)
        if len(nodes) < 2:
            raise MapError(source, path, "a route needs at least a start and a goal")
        rows = tuple(_node_row(source, f"{path}[{k}]", v, index) for k, v in enumerate(nodes))
        if rows[0] == rows[-1]:
            raise MapError(source, path, "a route must end at a node other than its start")
        routes.append(rows)
    return tuple(routes)


def _parse_zones(source: str, raw: Any) -> tuple:
    zones = []
    for i, zone in enumerate(_expect_list(source, "$.zones", raw)):
        path = f"$.zones[{i}]"
        _expect_keys(source, path, zone, ("name", "rect"))
        if not isinstance(zone["name"], str):
            raise MapError(source, f"{path}.name", "expected a string")
        rect = tuple(_expect_number(source, f"{path}.rect[{k}]", v)
                     for k, v in enumerate(_expect_list(source, f"{path}.rect", zone["rect"], 4)))
        if not (rect[0] < rect[2] and rect[1] < rect[3]):
            raise MapError(source, f"{path}.rect", "expected xmin < xmax and ymin < ymax")
        zones.append(Zone(zone["name"], rect))  # type: ignore[arg-type]
    return tuple(zones)


def _check_connected_pairs(spec: MapSpec) -> None:
    from sgjax.maps.routing import connected_components

    component = connected_components(spec.num_nodes, spec.edges)
    for i, (starts, goals) in enumerate(spec.groups):
        for s in starts:
            for g in goals:
                if s != g and component[s] != component[g]:
                    raise MapError(
                        spec.source, f"$.groups[{i}]",
                        f"no path in the graph from start {spec.node_ids[s]} "
                        f"to goal {spec.node_ids[g]}",
                    )
    for i, route in enumerate(spec.routes):
        if component[route[0]] != component[route[-1]]:
            raise MapError(spec.source, f"$.routes[{i}]",
                           f"no path in the graph from start {spec.node_ids[route[0]]} to goal "
                           f"{spec.node_ids[route[-1]]}")
