"""The largest map sgjax reads: stated limits, checked before any other work on a map.

Loading, ``sgjax maps check`` and the editor's server all refuse a map past these limits with an
error naming the list and the limit, instead of spending minutes or the machine's memory on it:

- walls: :data:`MAX_WALLS` (SocialGym 2.0's largest floor, GDC3, has 5,647);
- navigation nodes: :data:`MAX_NODES` (shortest paths are all-pairs, cubic in the nodes: 1,000
  nodes take a few seconds on the host; the largest shipped or SocialGym graph has 83);
- edges: :data:`MAX_EDGES` (SocialGym's open space has 2,256);
- groups, pedestrian groups, routes and zones: :data:`MAX_LIST_ITEMS` each;
- density: at most :data:`MAX_WALLS_PER_CELL` walls through any :data:`DENSITY_CELL` m square
  (a hand-drawn or imported floor has a few; a pillar drawn as a 32-gon has 32).
"""

from __future__ import annotations

from typing import Any

MAX_WALLS = 250_000
MAX_NODES = 1_000
MAX_EDGES = 20_000
MAX_LIST_ITEMS = 1_000  # groups, pedestrian_groups, routes, zones: each
MAX_WALLS_PER_CELL = 256
DENSITY_CELL = 0.5  # m: the side of the squares the density limit counts walls in

LIST_LIMITS = {"walls": MAX_WALLS, "nodes": MAX_NODES, "edges": MAX_EDGES,
               "groups": MAX_LIST_ITEMS, "pedestrian_groups": MAX_LIST_ITEMS,
               "routes": MAX_LIST_ITEMS, "zones": MAX_LIST_ITEMS}


def oversized_lists(data: Any) -> list[tuple[str, str]]:
    """``(JSON path, problem)`` for every list of a decoded map past its limit (nothing else is
    looked at: this runs before any other work)."""
    if not isinstance(data, dict):
        return []
    found = []
    for key, limit in LIST_LIMITS.items():
        items = data.get(key)
        if isinstance(items, list) and len(items) > limit:
            found.append((f"$.{key}", f"{len(items):,} {key}; a map has at most {limit:,} "
                                      f"(sgjax.maps.size_limits.LIST_LIMITS, docs/maps.md)"))
    return found


def density_problem(count: int, centre: Any, cell: float = DENSITY_CELL) -> str:
    """The error for ``count`` walls through one ``cell`` m square at ``centre``."""
    return (f"{count:,} walls pass through the {cell:g} m square around "
            f"({centre[0]:.2f}, {centre[1]:.2f}); at most {MAX_WALLS_PER_CELL} may "
            "(sgjax.maps.size_limits.MAX_WALLS_PER_CELL): walls that dense are not a floor plan")
