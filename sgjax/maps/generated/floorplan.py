"""The floor-plan family: a building of rooms on a grid (up to 4 x 3 rooms, each column and row
its own size), doors on a random spanning tree of adjacent rooms plus extra doors, and an
optional corridor: a row of the grid with no walls along it, a door from every room beside it.
Robots start in one room and go to another, and others make the reverse trip (two pairs of
rooms), so opposed flows meet in the doors between them (the dilemma).

The graph is built with the plan: each room's centre, and each door's two approach nodes, one
on each side of the wall in front of the door (so a robot goes through a door straight); a
route is centre, approach, approach, centre, ... Each door is a conflict zone, spanning its
two approach nodes. The spanning tree is Kruskal's: the adjacencies in a random order (the
corridor's first), each taken when it joins two rooms not yet joined; a fixed loop over the
24 adjacencies, the components a label per cell."""

from __future__ import annotations

from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from sgjax.maps.generated.family import Family, Parameter
from sgjax.maps.generated.floorplan_layout import (
    CELLS,
    COLUMNS,
    DOORS,
    EDGES,
    FIRST_APPROACH,
    FIRST_SPAWN,
    NODES,
    PAIRS,
    ROWS,
    SLOTS,
    SPAWN_COLUMNS,
    SPAWN_ROWS,
    SPAWNS,
    VERTICAL,
    WALLS,
)
from sgjax.maps.generated.floorplan_routes import floorplan_routes
from sgjax.maps.generated.lattice import lattice
from sgjax.maps.generated.world import FAR, Capacity, World, padded_walls

SPREAD = 0.15  # each column's width and row's height: the room size times 1 +- this
DOOR_SPREAD = 0.1  # each door's width: the drawn width times 1 +- this
DOOR_END = 0.5  # m: a door keeps this far from the ends of its wall
APPROACH = 0.8  # m: a door's approach nodes stand this far off its wall
MARGIN = 0.6  # m: spawns keep this far from a room's walls
ZONE_MARGIN = 0.5  # m: a door's zone reaches this far past its sides


PARAMETERS = {
    "rooms_x": Parameter((2.0, 4.999), (2.0, 4.999), "", "rooms across (the integer part)"),
    "rooms_y": Parameter((2.0, 3.999), (1.0, 3.999), "", "rows of rooms (the integer part)"),
    "room_size": Parameter((4.5, 6.5), (4.0, 8.0), "m", "a room's side (each column's width "
                           "and row's height drawn within 15% of it)"),
    "door_width": Parameter((1.0, 1.6), (0.8, 2.5), "m", "a door's free width (each door's "
                            "within 10% of it, at most its wall less 1 m)"),
    "extra_doors": Parameter((0.0, 0.5), (0.0, 1.0), "", "the share of neighbouring rooms off "
                             "the spanning tree that get a door too"),
    "corridor": Parameter((0.0, 1.999), (0.0, 1.999), "", "a corridor between the rows of "
                          "rooms (the integer part: 1 builds one)"),
    "corridor_width": Parameter((1.8, 2.6), (1.4, 3.0), "m", "the corridor's width"),
}
CAPACITY = Capacity(walls=WALLS, nodes=NODES, edges=EDGES, hubs=CELLS + 2 * DOORS,
                    groups=SLOTS, zones=DOORS, route_nodes=2 + CELLS + 2 * (CELLS - 1),
                    extent=(-19.0, -16.5, 19.0, 16.5), cell_walls=WALLS - 1)


def grid_lines(values: Mapping[str, Array], key: Array
               ) -> tuple[Array, Array, Array, Array, Array]:
    """``(xs [COLUMNS + 1], ys [ROWS + 1], present [CELLS], corridor [CELLS], counts [2])``:
    the grid's lines (m, the used part centred on the origin; lines past it repeat the last),
    which cells are part of the building, which are the corridor's, and the used columns and
    rows. The corridor row goes in the middle of the rows of rooms (below them with one)."""
    nx = jnp.floor(values["rooms_x"]).astype(jnp.int32)
    rooms_y = jnp.floor(values["rooms_y"]).astype(jnp.int32)
    has_corridor = jnp.floor(values["corridor"]) >= 1.0
    ny = rooms_y + has_corridor.astype(jnp.int32)
    k_x, k_y = jax.random.split(key)
    size = values["room_size"]
    widths = size * jax.random.uniform(k_x, (COLUMNS,), jnp.float32, 1 - SPREAD, 1 + SPREAD)
    row = jnp.arange(ROWS)
    corridor_row = has_corridor & (row == rooms_y // 2)
    heights = jnp.where(corridor_row, values["corridor_width"],
                        size * jax.random.uniform(k_y, (ROWS,), jnp.float32, 1 - SPREAD,
                                                  1 + SPREAD))
    widths = jnp.where(jnp.arange(COLUMNS) < nx, widths, 0.0)
    heights = jnp.where(row < ny, heights, 0.0)
    xs = jnp.concatenate([jnp.zeros(1), jnp.cumsum(widths)])
    ys = jnp.concatenate([jnp.zeros(1), jnp.cumsum(heights)])
    xs, ys = xs - xs[-1] / 2, ys - ys[-1] / 2
    column, row_of = jnp.arange(CELLS) % COLUMNS, jnp.arange(CELLS) // COLUMNS
    present = (column < nx) & (row_of < ny)
    return xs, ys, present, present & corridor_row[row_of], jnp.stack([nx, ny])


def spanning_doors(present: Array, corridor: Array, extra: Array, key: Array) -> Array:
    """``[DOORS]`` bool: the adjacencies with a door (or, inside the corridor, an opening):
    Kruskal's spanning tree over the ``present [CELLS]`` cells, taking first the corridor's
    openings and a door from every room beside it, then the rest in a random order; then each
    adjacency off the tree with probability ``extra``."""
    a, b = jnp.asarray(PAIRS[:, 0]), jnp.asarray(PAIRS[:, 1])
    usable = present[a] & present[b]
    forced = usable & (corridor[a] | corridor[b])
    k_order, k_extra = jax.random.split(key)
    weight = jnp.where(forced, -1.0, jax.random.uniform(k_order, (DOORS,)))
    order = jnp.argsort(weight)

    def join(k: int, carry: tuple[Array, Array]) -> tuple[Array, Array]:
        label, taken = carry
        e = order[k]
        la, lb = label[a[e]], label[b[e]]
        take = usable[e] & (la != lb)
        label = jnp.where(take & (label == lb), la, label)
        return label, taken.at[e].set(take)

    _, tree = jax.lax.fori_loop(0, DOORS, join, (jnp.arange(CELLS), jnp.zeros(DOORS, bool)))
    more = usable & (jax.random.uniform(k_extra, (DOORS,)) < extra)
    return tree | more


def door_geometry(xs: Array, ys: Array, doors: Array, openings: Array,
                  values: Mapping[str, Array], key: Array
                  ) -> tuple[Array, Array, Array, Array, Array]:
    """Each adjacency's wall and door: ``(pieces [2 DOORS, 4], piece_valid [2 DOORS],
    centre [DOORS, 2], normal [DOORS, 2], width [DOORS])``: the wall up to the door and on from
    it (the whole wall in the first piece where there is no door; none at an opening), the
    door's centre on the wall, the unit normal from its first cell to its second, and its free
    width (an opening's: the wall's length)."""
    a = PAIRS[:, 0]
    column, row = a % COLUMNS, a // COLUMNS
    vertical = jnp.asarray(VERTICAL)
    # a vertical wall: x = xs[column + 1], y from ys[row] to ys[row + 1]; a horizontal one:
    # y = ys[row + 1], x from xs[column] to xs[column + 1]
    start = jnp.where(vertical[:, None],
                      jnp.stack([xs[column + 1], ys[row]], -1),
                      jnp.stack([xs[column], ys[row + 1]], -1))
    along = jnp.where(vertical[:, None], jnp.asarray([0.0, 1.0]), jnp.asarray([1.0, 0.0]))
    normal = jnp.where(vertical[:, None], jnp.asarray([1.0, 0.0]), jnp.asarray([0.0, 1.0]))
    length = jnp.where(vertical, ys[row + 1] - ys[row], xs[column + 1] - xs[column])
    k_width, k_place = jax.random.split(key)
    width = values["door_width"] * jax.random.uniform(k_width, (DOORS,), jnp.float32,
                                                      1 - DOOR_SPREAD, 1 + DOOR_SPREAD)
    width = jnp.minimum(width, length - 2 * DOOR_END)
    room = jnp.maximum(length - 2 * DOOR_END - width, 0.0)  # where the door's start may go
    lo = DOOR_END + jax.random.uniform(k_place, (DOORS,)) * room
    lo = jnp.where(openings, 0.0, lo)
    width = jnp.where(openings, length, width)
    hi = lo + width
    end = start + length[:, None] * along
    first = jnp.concatenate([start, jnp.where(doors[:, None], start + lo[:, None] * along,
                                              end)], -1)
    second = jnp.concatenate([start + hi[:, None] * along, end], -1)
    pieces = jnp.concatenate([first, second])
    piece_valid = jnp.concatenate([~openings, doors & ~openings])
    centre = start + ((lo + hi) / 2)[:, None] * along
    return pieces, piece_valid, centre, normal, width


def room_pairs(present: Array, corridor: Array, key: Array) -> Array:
    """``[SLOTS]`` cells the spawn lattices go in: distinct rooms (not the corridor's) in a
    random order, repeated when there are fewer rooms than slots; slots 0 and 1 are one pair,
    2 and 3 another."""
    room = present & ~corridor
    priority = jax.random.uniform(key, (CELLS,)) + jnp.where(room, 0.0, 2.0)
    order = jnp.argsort(priority)
    count = jnp.maximum(jnp.sum(room), 1)
    return order[jnp.arange(SLOTS) % count]


def build(values: Mapping[str, Array], key: Array) -> World:
    """A floor-plan world of the parameter ``values``; ``key`` draws the column and row sizes,
    the doors, their widths and places, the rooms robots travel between, and the spawn
    jitter."""
    k_grid, k_doors, k_geometry, k_rooms, k_spawn = jax.random.split(key, 5)
    xs, ys, present, corridor, counts = grid_lines(values, k_grid)
    a, b = jnp.asarray(PAIRS[:, 0]), jnp.asarray(PAIRS[:, 1])
    doors = spanning_doors(present, corridor, values["extra_doors"], k_doors)
    openings = doors & corridor[a] & corridor[b]
    pieces, piece_valid, centre, normal, width = door_geometry(xs, ys, doors, openings, values,
                                                               k_geometry)
    usable = present[a] & present[b]
    x0, x1, y0, y1 = xs[0], xs[counts[0]], ys[0], ys[counts[1]]
    outside = jnp.stack([jnp.stack([x0, y0, x1, y0]), jnp.stack([x1, y0, x1, y1]),
                         jnp.stack([x1, y1, x0, y1]), jnp.stack([x0, y1, x0, y0])])
    walls, valid = padded_walls(jnp.concatenate([pieces, outside]), CAPACITY.walls,
                                jnp.concatenate([piece_valid & jnp.tile(usable, 2),
                                                 jnp.ones(4, bool)]))
    column, row = jnp.arange(CELLS) % COLUMNS, jnp.arange(CELLS) // COLUMNS
    xs_next, ys_next = xs[jnp.minimum(column + 1, COLUMNS)], ys[jnp.minimum(row + 1, ROWS)]
    centres = jnp.stack([(xs[column] + xs_next) / 2, (ys[row] + ys_next) / 2], -1)
    approach = jnp.concatenate([centre - APPROACH * normal, centre + APPROACH * normal])
    slots = room_pairs(present, corridor, k_rooms)
    boxes = jnp.stack([xs[column], ys[row], xs_next, ys_next], -1)[slots]
    spawns = jax.vmap(lambda k, box: lattice(k, box, SPAWN_COLUMNS, SPAWN_ROWS, MARGIN))(
        jax.random.split(k_spawn, SLOTS), boxes)
    nodes = jnp.concatenate([centres, approach, spawns.reshape(-1, 2)])
    node_valid = jnp.concatenate([present, doors, doors, jnp.ones(SLOTS * SPAWNS, bool)])
    near, far = FIRST_APPROACH + np.arange(DOORS), FIRST_APPROACH + DOORS + np.arange(DOORS)
    spawn_rows = FIRST_SPAWN + np.arange(SLOTS * SPAWNS)
    edges = jnp.concatenate([
        jnp.stack([a, jnp.asarray(near, jnp.int32)], 1),
        jnp.asarray(np.stack([near, far], 1), jnp.int32),
        jnp.stack([jnp.asarray(far, jnp.int32), b], 1),
        jnp.stack([jnp.repeat(slots, SPAWNS).astype(jnp.int32),
                   jnp.asarray(spawn_rows, jnp.int32)], 1)])
    slot_of = np.repeat(np.arange(SLOTS), SPAWNS)
    mine = jnp.zeros((SLOTS, NODES), bool).at[slot_of, spawn_rows].set(True)
    partner = np.asarray([1, 0, 3, 2])  # each slot's robots go to its partner's room
    is_door = doors & ~openings
    side = normal[:, ::-1]  # along the wall
    half_span = width / 2 + ZONE_MARGIN
    corner_a = centre - APPROACH * normal - half_span[:, None] * side
    corner_b = centre + APPROACH * normal + half_span[:, None] * side
    zones = jnp.concatenate([jnp.minimum(corner_a, corner_b), jnp.maximum(corner_a, corner_b)],
                            -1)
    zones = jnp.where(is_door[:, None], zones, jnp.asarray([FAR, FAR, FAR + 1.0, FAR + 1.0]))
    return World(
        walls=walls, wall_valid=valid, nodes=nodes, node_valid=node_valid, edges=edges,
        edge_valid=jnp.concatenate([doors, doors, doors, jnp.ones(SLOTS * SPAWNS, bool)]),
        group_starts=mine, group_goals=mine[partner], zones=zones,
        zone_width=jnp.where(is_door, width, FAR), zone_valid=is_door,
        bounds=jnp.stack([x0 - 0.5, y0 - 0.5, x1 + 0.5, y1 + 0.5]),
        made=jnp.asarray(True), dilemma=jnp.asarray(True))


FLOORPLAN = Family("floorplan", "rooms on a grid joined by doors on a random spanning tree "
                   "plus extra doors, with an optional corridor; robots cross between two pairs "
                   "of rooms both ways", PARAMETERS, CAPACITY, build, routes=floorplan_routes)
