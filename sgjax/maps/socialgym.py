"""Importer for SocialGym 2.0's own map files.

SocialGym 2.0 keeps a map as ``<name>.vectormap.txt`` (one wall ``x1, y1, x2, y2`` per line,
metres) or ``<name>.vectormap.json`` (a list of ``{"p0": {"x", "y"}, "p1": {...}}`` with numbers
as strings), and ``<name>.navigation.json`` (graph_navigation V2:
``{"nodes": [{"id", "loc": {"x", "y"}}], "edges": [{"s0_id", "s1_id", ...}]}``). Its scenarios
(which start goes to which goal) live in Python code, so they are passed here as ``routes`` or
``groups``; without them every node is both a start and a goal.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from sgjax.maps.schema import DEFAULT_CLEARANCE, MapError, MapSpec, parse_map


def read_vectormap_txt(path: Path) -> list[list[float]]:
    """Walls from a ``.vectormap.txt`` file: ``[[x1, y1, x2, y2], ...]``."""
    walls = []
    for lineno, line in enumerate(path.read_text().splitlines(), start=1):
        if not line.strip():
            continue
        parts = [p.strip() for p in line.split(",")]
        if len(parts) != 4:
            raise MapError(str(path), f"line {lineno}", f"expected 'x1, y1, x2, y2', got {line!r}")
        try:
            walls.append([float(p) for p in parts])
        except ValueError:
            raise MapError(str(path), f"line {lineno}", f"not a number in {line!r}") from None
    return walls


def read_vectormap_json(path: Path) -> list[list[float]]:
    """Walls from a ``.vectormap.json`` file (numbers may be strings)."""
    data = json.loads(path.read_text())
    walls = []
    for i, line in enumerate(data):
        try:
            walls.append([float(line["p0"]["x"]), float(line["p0"]["y"]),
                          float(line["p1"]["x"]), float(line["p1"]["y"])])
        except (KeyError, TypeError, ValueError) as err:
            raise MapError(str(path), f"$[{i}]", f"expected p0/p1 with x and y: {err}") from None
    return walls


def read_navigation_json(path: Path) -> tuple[list[dict[str, Any]], list[list[int]]]:
    """Nodes and edges from a graph_navigation V2 ``.navigation.json`` file."""
    data = json.loads(path.read_text())
    nodes, edges = [], []
    for i, node in enumerate(data.get("nodes", [])):
        try:
            nodes.append({"id": int(node["id"]),
                          "position": [float(node["loc"]["x"]), float(node["loc"]["y"])]})
        except (KeyError, TypeError, ValueError) as err:
            raise MapError(str(path), f"$.nodes[{i}]",
                           f"expected id and loc.x/loc.y: {err}") from None
    for i, edge in enumerate(data.get("edges", [])):
        try:
            edges.append([int(edge["s0_id"]), int(edge["s1_id"])])
        except (KeyError, TypeError, ValueError) as err:
            raise MapError(str(path), f"$.edges[{i}]", f"expected s0_id and s1_id: {err}") from None
    return nodes, edges


def import_socialgym(
    folder: str | Path,
    name: str | None = None,
    routes: list[list[int]] | None = None,
    groups: list[dict[str, list[int]]] | None = None,
    clearance: float = DEFAULT_CLEARANCE,
) -> MapSpec:
    """Load a SocialGym 2.0 map folder (``<name>.vectormap.txt|json`` + ``<name>.navigation.json``).

    ``name`` defaults to the folder's name. ``routes`` are SocialGym ``ManualScenario`` paths
    (lists of node ids); ``groups`` are ``{"starts": [...], "goals": [...]}``; with neither,
    every node is both a start and a goal (SocialGym's ``GraphNavScenario``).
    """
    folder = Path(folder)
    name = name or folder.name
    txt, js = folder / f"{name}.vectormap.txt", folder / f"{name}.vectormap.json"
    if txt.exists():
        walls = read_vectormap_txt(txt)
    elif js.exists():
        walls = read_vectormap_json(js)
    else:
        raise FileNotFoundError(f"no {txt.name} or {js.name} in {folder}")
    nav = folder / f"{name}.navigation.json"
    if not nav.exists():
        raise FileNotFoundError(f"no {nav.name} in {folder}")
    nodes, edges = read_navigation_json(nav)
    kept = [w for w in walls if (w[0], w[1]) != (w[2], w[3])]
    dropped = len(walls) - len(kept)  # SocialGym's intersection ships 4 zero-length stubs
    walls = kept
    xs = [w[0] for w in walls] + [w[2] for w in walls] + [n["position"][0] for n in nodes]
    ys = [w[1] for w in walls] + [w[3] for w in walls] + [n["position"][1] for n in nodes]
    data: dict[str, Any] = {
        "name": name,
        "description": f"imported from SocialGym 2.0 files in {folder}"
        + (f"; dropped {dropped} zero-length wall(s)" if dropped else ""),
        "bounds": [min(xs) - 1.0, min(ys) - 1.0, max(xs) + 1.0, max(ys) + 1.0],
        "walls": walls,
        "nodes": nodes,
        "edges": edges,
    }
    if routes is not None:
        data["routes"] = routes
    if groups is not None:
        data["groups"] = groups
    if routes is None and groups is None:
        all_ids = [n["id"] for n in nodes]
        data["groups"] = [{"starts": all_ids, "goals": all_ids}]
    return parse_map(data, source=str(nav), clearance=clearance)
