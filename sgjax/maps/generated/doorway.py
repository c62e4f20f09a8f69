"""The doorway family: two rooms and a door through the wall between them (SocialGym 2.0's
doorway is one of its worlds: rooms 9.5 m deep and 12 m tall, a 1 m door in a 1 m wall)."""

from __future__ import annotations

from collections.abc import Mapping

from jax import Array

from sgjax.maps.generated.family import Family, Parameter
from sgjax.maps.generated.two_rooms import EDGES, NODES, WALLS, two_rooms
from sgjax.maps.generated.world import Capacity, World

PARAMETERS = {
    "room_height": Parameter((8.0, 14.0), (5.0, 16.0), "m", "the rooms' extent across the "
                             "wall (y)"),
    "left_depth": Parameter((6.0, 10.0), (5.0, 12.0), "m", "the left room's depth (x)"),
    "right_depth": Parameter((6.0, 10.0), (5.0, 12.0), "m", "the right room's depth (x)"),
    "wall_thickness": Parameter((0.2, 1.5), (0.1, 2.0), "m", "the door's length"),
    "door_width": Parameter((0.9, 2.0), (0.6, 3.0), "m", "the door's free width"),
    "door_offset": Parameter((-0.5, 0.5), (-1.0, 1.0), "", "the door's centre off the middle, "
                             "a fraction of the most it can move (1 m from the corners)"),
    "ways": Parameter((2.0, 2.0), (1.0, 2.0), "", "the directions robots cross in: below "
                       "1.5 one way, left to right (a bottleneck queue, no dilemma), else both "
                       "ways (head-on: the social dilemma); default always both"),
}
CAPACITY = Capacity(walls=WALLS, nodes=NODES, edges=EDGES, hubs=2, groups=2, zones=1,
                    route_nodes=4,
                    extent=(-13.5, -8.5, 13.5, 8.5), cell_walls=WALLS - 1)


def build(values: Mapping[str, Array], key: Array) -> World:
    """A doorway world of the parameter ``values``; ``key`` jitters the spawn lattices."""
    return two_rooms(key, CAPACITY, values["room_height"], values["left_depth"],
                     values["right_depth"], values["wall_thickness"], values["door_width"],
                     values["door_offset"], ways=values["ways"])


DOORWAY = Family("doorway", "two rooms joined by a door; robots cross both ways (or one way: "
                 "ways)",
                 PARAMETERS, CAPACITY, build)
