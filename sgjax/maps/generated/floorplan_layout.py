"""A floor plan's static layout: the grid of cells, the adjacencies between them (each a wall
that may hold a door) and the rows of the graph's nodes, walls and edges (shared by
:mod:`sgjax.maps.generated.floorplan`, which builds a world, and
:mod:`sgjax.maps.generated.floorplan_routes`, which routes it)."""

from __future__ import annotations

import numpy as np

COLUMNS, ROWS = 4, 4  # the grid's capacity: 4 x 3 rooms and a corridor row
CELLS = COLUMNS * ROWS
SLOTS = 4  # spawn lattices: two pairs of rooms, each room's robots going to the other
SPAWN_COLUMNS = SPAWN_ROWS = 3
SPAWNS = SPAWN_COLUMNS * SPAWN_ROWS


def _adjacencies() -> tuple[np.ndarray, np.ndarray]:
    """``(cells [24, 2], vertical [24])``: each pair of neighbouring grid cells (cell = row x
    COLUMNS + column), left-right pairs first (their wall is vertical), then bottom-top."""
    pairs, vertical = [], []
    for j in range(ROWS):
        for i in range(COLUMNS - 1):
            pairs.append((j * COLUMNS + i, j * COLUMNS + i + 1))
            vertical.append(True)
    for j in range(ROWS - 1):
        for i in range(COLUMNS):
            pairs.append((j * COLUMNS + i, (j + 1) * COLUMNS + i))
            vertical.append(False)
    return np.asarray(pairs, np.int32), np.asarray(vertical)


PAIRS, VERTICAL = _adjacencies()
DOORS = len(PAIRS)
# node rows: cell centres, then each door's approach nodes (its first cell's side, then its
# second's), then the spawn lattices
FIRST_APPROACH = CELLS
FIRST_SPAWN = CELLS + 2 * DOORS
NODES = FIRST_SPAWN + SLOTS * SPAWNS
WALLS = 2 * DOORS + 4 + 1  # each adjacency's wall in two pieces (a door between), the outside
EDGES = 3 * DOORS + SLOTS * SPAWNS
