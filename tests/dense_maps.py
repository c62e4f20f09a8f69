"""Maps dense or large enough to test the map checks' limits and cost (the editor's security
report: 200,000 short walls packed into one room; ``bench/map_check.py`` times them too)."""

from __future__ import annotations

from typing import Any

import numpy as np


def packed_room(count: int, size: float = 20.0, length: float = 0.1, seed: int = 0
                ) -> dict[str, Any]:
    """A ``size`` m square room with ``count`` walls ``length`` m long scattered over it at
    random angles, a node near either side wall and an edge between them (which the walls
    cross) as map JSON."""
    rng = np.random.default_rng(seed)
    h = size / 2
    centres = rng.uniform(-h + 1, h - 1, (count, 2))
    angle = rng.uniform(0, np.pi, count)
    half = length / 2 * np.stack([np.cos(angle), np.sin(angle)], 1)
    walls = np.concatenate([centres - half, centres + half], 1).round(3).tolist()
    return {"name": "packed", "description": f"{count} walls of {length} m in a {size} m room",
            "bounds": [-h - 1, -h - 1, h + 1, h + 1],
            "walls": [[-h, -h, h, -h], [h, -h, h, h], [h, h, -h, h], [-h, h, -h, -h]] + walls,
            "nodes": [{"id": 0, "position": [-h + 0.5, 0]}, {"id": 1, "position": [h - 0.5, 0]}],
            "edges": [[0, 1]], "groups": [{"starts": [0], "goals": [1]}]}
