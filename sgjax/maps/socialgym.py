"""Importer for SocialGym 2.0's own map files.

SocialGym 2.0 keeps a map as ``<name>.vectormap.txt`` (one wall ``x1, y1, x2, y2`` per line,
metres) or ``<name>.vectormap.json`` (a list of ``{"p0": {"x", "y"}, "p1": {...}}`` with numbers
as strings), and ``<name>.navigation.json`` (graph_navigation V2:
``{"nodes": [{"id", "loc": {"x", "y"}}], "edges": [{"s0_id", "s1_id", ...}]}``). Its scenarios
(which start goes to which goal) live in Python code, so they are passed here as ``routes``
(SocialGym's ``ManualScenario`` paths, ``[start, waypoint, ..., goal]``) or ``groups``; without
them, every connected part of the graph is one group whose nodes are all starts and goals
(SocialGym's ``GraphNavScenario``).

How SocialGym ran these files, and what the import does the same way:

* Robots used only the first and last id of a path and planned with A* on the graph
  (graph_navigation); the ids in between were pedestrian waypoints, not graph edges. A route here
  is kept as given (its interior is not required to follow edges); robots drive the shortest graph
  path between its ends.
* Most spawn nodes of the real mini-games have no edge. graph_navigation added a start or goal as
  a *dynamic state* projected onto the closest edge, splitting the edge there
  (``../shared/reference/socialgym2.md`` section 1.3). The import does that once per edgeless node:
  of the edges whose nearest point to the node it can see (no wall in between, the point at least
  ``clearance`` from every wall), it takes the nearest and joins the node to that point, adding a
  node there (a new id above the file's) that splits the edge, or joining the edge's end when the
  nearest point is an end.
* Nodes closer than ``clearance`` to a wall (SocialGym never checked) are moved straight away
  from it until they keep it (exp1's test map has one 0.18 m from a wall).
* Edge attributes (``max_speed``, ``max_clearance``, ``has_door``, ``has_stairs``,
  ``has_elevator``, ``has_automated_door``) have no meaning in sgjax and are ignored; zero-length
  walls are dropped. All of it is reported in :attr:`ImportReport.lines`, also appended to the
  map's description.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from sgjax.kernels.geometry import segments_intersect_pairs
from sgjax.maps.routing import connected_components
from sgjax.maps.schema import (
    DEFAULT_CLEARANCE,
    MapError,
    MapSpec,
    checked_coordinate,
    parse_map,
    point_segment_distances,
)

EDGE_ATTRIBUTES = ("max_speed", "max_clearance", "has_door", "has_stairs", "has_elevator",
                   "has_automated_door")
SAME_POINT = 1e-6  # m: a projection this close to an edge's end joins that end


@dataclasses.dataclass
class ImportReport:
    """What :func:`import_socialgym` changed or left out, for a person to read."""

    source: str
    dropped_walls: int = 0
    # (node, the node it was joined to (None: it lay on an edge, now split there), distance m)
    attached: list[tuple[int, int | None, float]] = dataclasses.field(default_factory=list)
    added_nodes: list[int] = dataclasses.field(default_factory=list)
    unattached: list[int] = dataclasses.field(default_factory=list)
    ignored_attributes: dict[str, str] = dataclasses.field(default_factory=dict)
    default_groups: int = 0
    moved: list[tuple[int, float]] = dataclasses.field(default_factory=list)
    other_map: str = ""  # a scenario written for another map file

    @property
    def lines(self) -> list[str]:
        """One sentence per kind of change (empty when nothing changed)."""
        out = [self.other_map] if self.other_map else []
        if self.dropped_walls:
            out.append(f"dropped {self.dropped_walls} zero-length wall(s)")
        if self.moved:
            out.append(f"moved {len(self.moved)} node(s) closer than the clearance to a wall away "
                       "from it: " + ", ".join(f"{node} by {shift:.3f} m"
                                               for node, shift in self.moved))
        if self.attached:
            joined = ", ".join(
                f"{node} on edge" if to is None
                else f"{node}->{'new ' if to in self.added_nodes else ''}{to}"
                for node, to, _ in self.attached)
            out.append(f"attached {len(self.attached)} edgeless node(s) to the nearest visible "
                       f"edge as graph_navigation did ({joined}); {len(self.added_nodes)} node(s) "
                       "added where an edge was split")
        if self.unattached:
            out.append(f"{len(self.unattached)} edgeless node(s) see no edge and stay apart: "
                       + ", ".join(str(n) for n in self.unattached))
        if self.ignored_attributes:
            out.append("ignored edge attributes: " + ", ".join(
                f"{name} ({values})" for name, values in self.ignored_attributes.items()))
        if self.default_groups:
            out.append(f"no routes or groups given: {self.default_groups} group(s), one per "
                       "connected part of the graph, every node of a part a start and a goal")
        return out

    def __str__(self) -> str:
        lines = self.lines
        if not lines:
            return f"{self.source}: imported unchanged"
        return f"{self.source}:\n" + "\n".join(f"  - {line}" for line in lines)


def read_vectormap_txt(path: Path) -> list[list[float]]:
    """Walls from a ``.vectormap.txt`` file: ``[[x1, y1, x2, y2], ...]``."""
    walls = []
    try:
        text = path.read_text()
    except UnicodeDecodeError as err:
        raise MapError(str(path), "$", f"not UTF-8 text ({err})") from None
    for lineno, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        parts = [p.strip() for p in line.split(",")]
        if len(parts) != 4:
            raise MapError(str(path), f"line {lineno}", f"expected 'x1, y1, x2, y2', got {line!r}")
        try:
            numbers = [float(p) for p in parts]
        except ValueError:
            raise MapError(str(path), f"line {lineno}", f"not a number in {line!r}") from None
        walls.append([checked_coordinate(str(path), f"line {lineno}", x) for x in numbers])
    return walls


def _read_json(path: Path) -> Any:
    """A JSON file's data; unreadable JSON is a ``MapError`` naming the file and the place."""
    try:
        return json.loads(path.read_text())
    except UnicodeDecodeError as err:
        raise MapError(str(path), "$", f"not UTF-8 text ({err})") from None
    except json.JSONDecodeError as err:
        raise MapError(str(path), f"line {err.lineno}", f"not JSON: {err.msg}") from None


def _items(path: Path, where: str, value: Any) -> list:
    """``value`` as a list (a JSON array), else a ``MapError`` at ``where``."""
    if not isinstance(value, list):
        raise MapError(str(path), where, f"expected a list, got {type(value).__name__}")
    return value


def read_vectormap_json(path: Path) -> list[list[float]]:
    """Walls from a ``.vectormap.json`` file (numbers may be strings)."""
    data = _items(path, "$", _read_json(path))
    walls = []
    for i, line in enumerate(data):
        try:
            numbers = [float(line["p0"]["x"]), float(line["p0"]["y"]),
                       float(line["p1"]["x"]), float(line["p1"]["y"])]
        except (KeyError, TypeError, ValueError) as err:
            raise MapError(str(path), f"$[{i}]", f"expected p0/p1 with x and y: {err}") from None
        walls.append([checked_coordinate(str(path), f"$[{i}]", x) for x in numbers])
    return walls


def read_navigation_json(path: Path) -> tuple[list[dict[str, Any]], list[list[int]],
                                              dict[str, str]]:
    """Nodes, edges and a summary of the ignored edge attributes from a graph_navigation V2
    ``.navigation.json`` file."""
    data = _read_json(path)
    if not isinstance(data, dict):
        raise MapError(str(path), "$", f"expected an object with nodes and edges, got "
                       f"{type(data).__name__}")
    nodes, edges = [], []
    for i, node in enumerate(_items(path, "$.nodes", data.get("nodes", []))):
        try:
            node_id, xy = int(node["id"]), [float(node["loc"]["x"]), float(node["loc"]["y"])]
        except (KeyError, TypeError, ValueError) as err:
            raise MapError(str(path), f"$.nodes[{i}]",
                           f"expected id and loc.x/loc.y: {err}") from None
        nodes.append({"id": node_id, "position": [
            checked_coordinate(str(path), f"$.nodes[{i}].loc", x) for x in xy]})
    values: dict[str, list] = {name: [] for name in EDGE_ATTRIBUTES}
    for i, edge in enumerate(_items(path, "$.edges", data.get("edges", []))):
        try:
            edges.append([int(edge["s0_id"]), int(edge["s1_id"])])
        except (KeyError, TypeError, ValueError) as err:
            raise MapError(str(path), f"$.edges[{i}]", f"expected s0_id and s1_id: {err}") from None
        for name in EDGE_ATTRIBUTES:
            if name in edge:
                values[name].append(edge[name])
    ignored = {}
    for name, seen in values.items():
        if seen:
            distinct = sorted({json.dumps(v) for v in seen})
            shown = ", ".join(distinct[:4]) + (", ..." if len(distinct) > 4 else "")
            ignored[name] = f"{shown} on {len(seen)} edge(s)"
    return nodes, edges, ignored


def _visible(a: np.ndarray, b: np.ndarray, walls: np.ndarray) -> bool:
    return not segments_intersect_pairs(np.concatenate([a, b])[None], walls).any()


def keep_clear_of_walls(nodes: list[dict[str, Any]], walls: np.ndarray, clearance: float,
                        report: ImportReport) -> list[dict[str, Any]]:
    """Move each node closer than ``clearance`` to a wall straight away from its nearest wall
    point until it keeps the clearance (a robot spawned there would start inside the wall;
    SocialGym never checked). A node that cannot be cleared this way (a gap narrower than twice
    the clearance) is left where it is, for the map validator to report."""
    if not walls.shape[0]:
        return nodes
    moved = []
    for node in nodes:
        start = np.asarray(node["position"], float)
        p = start.copy()
        for _ in range(8):
            dist = point_segment_distances(p[None], walls)[0]
            w = int(np.argmin(dist))
            if dist[w] >= clearance:
                break
            a, b = walls[w, :2], walls[w, 2:]
            t = np.clip(np.dot(p - a, b - a) / max(float(np.dot(b - a, b - a)), 1e-12), 0, 1)
            away = p - (a + t * (b - a))
            norm = float(np.linalg.norm(away))
            if norm < 1e-9:
                break
            p = p + away / norm * (clearance - dist[w] + 1e-4)
        ok = point_segment_distances(p[None], walls).min() >= clearance and _visible(start, p,
                                                                                    walls)
        if ok and not np.allclose(p, start):
            report.moved.append((node["id"], float(np.linalg.norm(p - start))))
            node = {**node, "position": p.tolist()}
        moved.append(node)
    return moved


def attach_edgeless_nodes(
    nodes: list[dict[str, Any]], edges: list[list[int]], walls: np.ndarray, clearance: float,
    report: ImportReport,
) -> tuple[list[dict[str, Any]], list[list[int]]]:
    """Join every node without an edge to the nearest point of the nearest visible edge (only
    the file's own edges; several nodes landing on one edge split it several times)."""
    ids = [n["id"] for n in nodes]
    position = {n["id"]: np.asarray(n["position"], float) for n in nodes}
    linked = {i for edge in edges for i in edge}
    lonely = [i for i in ids if i not in linked]
    usable = [e for e, (s0, s1) in enumerate(edges) if s0 in position and s1 in position]
    if not lonely or not usable:  # (edges naming missing nodes: parse_map reports them)
        report.unattached = lonely
        return nodes, edges
    next_id = max(ids) + 1
    cuts: dict[int, list[tuple[float, int]]] = {}  # edge index -> (fraction along it, new id)
    joins: list[list[int]] = []
    for node in lonely:
        p = position[node]
        best = None
        for e in usable:
            s0, s1 = edges[e]
            a, b = position[s0], position[s1]
            ab = b - a
            t = float(np.clip(np.dot(p - a, ab) / max(float(np.dot(ab, ab)), 1e-12), 0.0, 1.0))
            point = a + t * ab
            distance = float(np.linalg.norm(point - p))
            if best is not None and distance >= best[0]:
                continue
            if walls.shape[0] and (not _visible(p, point, walls) or float(
                    point_segment_distances(point[None], walls).min()) < clearance):
                continue
            best = (distance, e, t)
        if best is None:
            report.unattached.append(node)
            continue
        distance, e, t = best
        length = float(np.linalg.norm(position[edges[e][1]] - position[edges[e][0]]))
        if t * length < SAME_POINT:
            target = edges[e][0]
        elif (1.0 - t) * length < SAME_POINT:
            target = edges[e][1]
        else:
            same = [new for frac, new in cuts.get(e, []) if abs(frac - t) * length < SAME_POINT]
            if same:
                target = same[0]
            elif distance < SAME_POINT:  # the node lies on the edge: the edge runs through it
                cuts.setdefault(e, []).append((t, node))
                report.attached.append((node, None, 0.0))
                continue
            else:
                target = next_id
                next_id += 1
                cuts.setdefault(e, []).append((t, target))
                a, b = position[edges[e][0]], position[edges[e][1]]
                position[target] = a + t * (b - a)
                report.added_nodes.append(target)
        joins.append([node, target])
        report.attached.append((node, target, distance))
    new_edges = []
    for e, (s0, s1) in enumerate(edges):
        chain = [s0] + [new for _, new in sorted(cuts.get(e, []))] + [s1]
        new_edges += [[chain[k], chain[k + 1]] for k in range(len(chain) - 1)]
    added = [{"id": i, "position": position[i].tolist()} for i in report.added_nodes]
    return nodes + added, new_edges + joins


def _default_groups(nodes: list[dict[str, Any]], edges: list[list[int]],
                    exclude: set[int]) -> list[dict[str, list[int]]]:
    """One group per connected part with at least two nodes of the file."""
    ids = [n["id"] for n in nodes]
    row = {node_id: i for i, node_id in enumerate(ids)}
    label = connected_components(len(ids), np.asarray(
        [[row[a], row[b]] for a, b in edges if a in row and b in row], dtype=np.int64
    ).reshape(-1, 2))
    parts: dict[int, list[int]] = {}
    for node_id, part in zip(ids, label, strict=True):
        if node_id not in exclude:
            parts.setdefault(int(part), []).append(node_id)
    return [{"starts": members, "goals": members} for members in parts.values()
            if len(members) >= 2]


def import_socialgym(
    folder: str | Path,
    name: str | None = None,
    routes: list[list[int]] | None = None,
    groups: list[dict[str, list[int]]] | None = None,
    clearance: float = DEFAULT_CLEARANCE,
    report: Callable[[ImportReport], None] | None = None,
    scenario: str | None = None,
) -> MapSpec:
    """Load a SocialGym 2.0 map folder (``<name>.vectormap.txt|json`` + ``<name>.navigation.json``).

    ``name`` defaults to the folder's name (or the single ``*.navigation.json`` in it).
    ``routes`` are SocialGym ``ManualScenario`` paths exactly as its scripts give them (lists of
    node ids ``[start, ..., goal]``: robots use the ends); ``groups`` are ``{"starts": [...],
    "goals": [...]}``; with neither, one group per connected part of the graph. Edgeless nodes
    are attached to the graph as graph_navigation did (module docstring); ``report``, when
    given, receives the :class:`ImportReport` (its lines are also in the description).

    ``scenario`` names one of SocialGym's own scenarios (:data:`SOCIALGYM_SCENARIOS`, e.g.
    ``"envs_door"``): its conflict zone (``build_zone``: x from the start hub to the end hub, y
    within the half-height of the start hub) becomes the map's zone, and its robot paths the
    routes unless ``routes`` / ``groups`` are given. A scenario written for another map file
    than this folder's is reported (SocialGym's ids repeat across maps, so it would load).
    """
    folder = Path(folder)
    map_files, zone = (), None
    if scenario is not None:
        map_files, scenario_routes, zone = _socialgym_scenario(scenario)
        if routes is None and groups is None:
            routes = scenario_routes
    if name is None:
        found = sorted(folder.glob("*.navigation.json"))
        name = found[0].name[: -len(".navigation.json")] if len(found) == 1 else folder.name
    nav = folder / f"{name}.navigation.json"
    if not nav.exists():
        raise FileNotFoundError(f"no {nav.name} in {folder}")
    nodes, edges, ignored = read_navigation_json(nav)
    walls = _read_walls(folder, name)
    info = ImportReport(source=str(folder), ignored_attributes=ignored)
    if scenario is not None and name not in map_files:
        info.other_map = (f"scenario {scenario} was written for SocialGym's "
                          f"{'/'.join(map_files)} map file(s), not {name}")
    kept = [w for w in walls if np.hypot(w[2] - w[0], w[3] - w[1]) >= SAME_POINT]
    info.dropped_walls = len(walls) - len(kept)  # SocialGym's intersection ships 4 stubs
    wall_array = np.asarray(kept, dtype=float).reshape(-1, 4)
    file_ids = {n["id"] for n in nodes}
    nodes = keep_clear_of_walls(nodes, wall_array, clearance, info)
    nodes, edges = attach_edgeless_nodes(nodes, edges, wall_array, clearance, info)
    xs = [w[0] for w in kept] + [w[2] for w in kept] + [n["position"][0] for n in nodes]
    ys = [w[1] for w in kept] + [w[3] for w in kept] + [n["position"][1] for n in nodes]
    data: dict[str, Any] = {
        "name": name,
        "description": f"imported from SocialGym 2.0 files in {folder}",
        "bounds": [min(xs) - 1.0, min(ys) - 1.0, max(xs) + 1.0, max(ys) + 1.0],
        "walls": kept,
        "nodes": nodes,
        "edges": edges,
    }
    if zone is not None:
        data["zones"] = [_zone_entry(scenario, zone, nodes, nav)]
    if routes is not None:
        data["routes"] = [list(route) for route in routes]
    if groups is not None:
        data["groups"] = groups
    if routes is None and groups is None:
        added = {n["id"] for n in nodes} - file_ids
        data["groups"] = _default_groups(nodes, edges, exclude=added)
        info.default_groups = len(data["groups"])
        if not data["groups"]:
            raise MapError(str(nav), "$.edges", "no two nodes are joined by the graph, so no "
                           "robot has anywhere to go (pass routes or groups)")
    if info.lines:
        data["description"] += "; " + "; ".join(info.lines)
    spec = parse_map(data, source=str(nav), clearance=clearance)
    if report is not None:
        report(info)
    return spec


def _socialgym_scenario(scenario: str) -> tuple[tuple[str, ...], list[list[int]], tuple]:
    """``(map files, robot paths, zone)`` of one of SocialGym's own scenarios, by name."""
    if scenario not in SOCIALGYM_SCENARIOS:
        close = difflib.get_close_matches(scenario, list(SOCIALGYM_SCENARIOS), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ValueError(f"unknown SocialGym scenario {scenario!r}{hint}; known: "
                         f"{', '.join(SOCIALGYM_SCENARIOS)}")
    return SOCIALGYM_SCENARIOS[scenario]


def _read_walls(folder: Path, name: str) -> list[list[float]]:
    """The wall segments of ``<name>.vectormap.txt``, or of the ``.json`` beside it when the text
    file is empty or missing (SocialGym's open map ships an empty .txt beside its .json)."""
    txt, js = folder / f"{name}.vectormap.txt", folder / f"{name}.vectormap.json"
    if not txt.exists() and not js.exists():
        raise FileNotFoundError(f"no {txt.name} or {js.name} in {folder}")
    walls = read_vectormap_txt(txt) if txt.exists() else []
    if not walls and js.exists():
        walls = read_vectormap_json(js)
    return walls


def _zone_entry(scenario: str, zone: tuple, nodes: list[dict], nav: Path) -> dict[str, Any]:
    """The map's conflict zone from a SocialGym scenario's ``build_zone``: x from the start hub
    to the end hub, y within ``half`` (m) of the start hub."""
    position = {n["id"]: n["position"] for n in nodes}
    missing = [i for i in zone[:2] if i not in position]
    if missing:
        raise MapError(str(nav), "$.nodes", f"scenario {scenario}'s conflict zone needs "
                       f"nodes {zone[0]} and {zone[1]}; this map has no node {missing[0]}")
    (x0, y0), (x1, _), half = position[zone[0]], position[zone[1]], zone[2]
    return {"name": scenario, "rect": [min(x0, x1), y0 - half, max(x0, x1), y0 + half]}


def _product(starts: list[int], via: list[int], goals: list[int]) -> list[list[int]]:
    return [[s, *via, g] for s in starts for g in goals]


# SocialGym 2.0's own scenarios (ut-amrl/SocialGym2 src/environment/scenarios/common_scenarios.py
# at 05b43db; node ids are facts of its map files): scenario name -> (the map file names
# ``<name>.navigation.json`` it was written for, robot paths, conflict zone (start node, end
# node, half-height m) or None).
_DOOR_STARTS = [0, 43, *range(1, 20)]
_BOTTOM, _LEFT = [0, 1, 30, 2, 3, 4, 31], list(range(5, 12))
_TOP, _RIGHT = list(range(12, 19)), list(range(19, 26))
SOCIALGYM_SCENARIOS: dict[str, tuple[tuple[str, ...], list[list[int]],
                                     tuple[int, int, float] | None]] = {
    "envs_door": (("door",), _product(_DOOR_STARTS, [20, 21], list(range(22, 43))), (20, 21, 1)),
    "envs_hallway": (("hallway",), _product(list(range(21)), [21, 22], list(range(23, 44))),
                     (21, 22, 1)),
    "envs_intersection": (("intersection",), _product(_BOTTOM, [29, 27], _TOP)
                          + _product(_LEFT, [26, 28], _RIGHT), (26, 28, 2)),
    "envs_round_about": (("round_about",), _product(_BOTTOM, [29, 27], _TOP + _RIGHT + _LEFT)
                         + _product(_LEFT, [26, 28], _TOP + _RIGHT + _BOTTOM), (26, 28, 2)),
    "envs_open": (("open",), [[i, j] for i in range(48) for j in range(48) if i != j],
                  (12, 36, 6)),
    "envs_multi": (("multienv",), [[0, 1], [1, 0], [1, 2]], None),
    "closed_door_1__same_goals": (("t1", "t2"), [[1, 4, 2, 5], [1, 4, 2, 0], [3, 4, 2, 5],
                                                 [3, 4, 2, 0]], None),
    "exp1_train_scenario": (("easy", "medium", "hard"), _product(
        [1, 6, 18, 17, 0, 10, 3, 8, 15, 12], [7, 11], [19, 5, 14, 4, 16, 9, 21, 2, 13, 20]), None),
}

