"""A generated world as a map file (the sgjax JSON map format, ``sgjax.maps.schema``): what
``sgjax maps check``, ``sgjax evaluate --scenario``, the trainer and the editor load."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from sgjax.maps.generated.world import World


def world_map(world: World, name: str, description: str,
              values: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The map-file dict of one world (host arrays or device arrays of one world, not a
    batch): its valid walls, its valid nodes (ids: their rows), edges, the groups that have
    starts and goals, and its valid zones; ``values`` (the parameters it was built from) go into the
    description."""
    w = {field: np.asarray(getattr(world, field)) for field in (
        "walls", "wall_valid", "nodes", "node_valid", "group_starts",
        "group_goals", "zones", "zone_valid", "bounds")}
    rows = np.flatnonzero(w["node_valid"])
    a, b = np.nonzero(np.triu(np.asarray(world.adjacency), 1))
    groups = [{"starts": np.flatnonzero(s & w["node_valid"]).tolist(),
               "goals": np.flatnonzero(g & w["node_valid"]).tolist()}
              for s, g in zip(w["group_starts"], w["group_goals"], strict=True)]
    if values:
        shown = ", ".join(f"{k} {float(v):.3f}" for k, v in sorted(values.items()))
        description = f"{description} ({shown})"
    return {
        "name": name, "description": description,
        "bounds": [round(float(v), 6) for v in w["bounds"]],
        "walls": [[round(float(v), 6) for v in wall] for wall in w["walls"][w["wall_valid"]]],
        "nodes": [{"id": int(r), "position": [round(float(v), 6) for v in w["nodes"][r]]}
                  for r in rows],
        "edges": [[int(i), int(j)] for i, j in zip(a, b, strict=True)],
        "groups": [g for g in groups if g["starts"] and g["goals"]],
        "zones": [{"name": f"zone {i}", "rect": [round(float(v), 6) for v in rect]}
                  for i, rect in enumerate(w["zones"][w["zone_valid"]])],
    }
