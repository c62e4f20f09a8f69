"""The hallway family: two rooms joined by a corridor, optionally with a lay-by niche in one
corridor wall where a robot can wait (SocialGym 2.0's hallway: a 6 m corridor 1 m wide)."""

from __future__ import annotations

from collections.abc import Mapping

from jax import Array

from sgjax.maps.generated.family import Family, Parameter
from sgjax.maps.generated.two_rooms import EDGES, NODES, WALLS, two_rooms
from sgjax.maps.generated.world import Capacity, World

PARAMETERS = {
    "room_height": Parameter((8.0, 12.0), (5.0, 14.0), "m", "the rooms' extent (y)"),
    "left_depth": Parameter((6.0, 9.0), (5.0, 10.0), "m", "the left room's depth (x)"),
    "right_depth": Parameter((6.0, 9.0), (5.0, 10.0), "m", "the right room's depth (x)"),
    "corridor_length": Parameter((4.0, 10.0), (2.0, 14.0), "m", "the corridor's length"),
    "corridor_width": Parameter((0.9, 2.0), (0.6, 3.0), "m", "the corridor's free width"),
    "corridor_offset": Parameter((-0.3, 0.3), (-1.0, 1.0), "", "the corridor's centre line off "
                                 "the middle, a fraction of the most it can move"),
    "layby_depth": Parameter((0.0, 1.2), (0.0, 1.5), "m", "the lay-by's depth into the upper "
                             "corridor wall (none below 0.4 m)"),
    "layby_at": Parameter((0.3, 0.7), (0.2, 0.8), "", "the lay-by's centre along the corridor "
                          "(a fraction of its length)"),
    "layby_length": Parameter((1.0, 2.0), (0.8, 3.0), "m", "the lay-by's length"),
    "ways": Parameter((2.0, 2.0), (1.0, 2.0), "", "the directions robots cross in: below "
                       "1.5 one way, left to right (a bottleneck queue, no dilemma), else both "
                       "ways (head-on: the social dilemma); default always both"),
}
CAPACITY = Capacity(walls=WALLS, nodes=NODES, edges=EDGES, hubs=2, groups=2, zones=1,
                    route_nodes=4,
                    extent=(-17.5, -7.5, 17.5, 7.5), cell_walls=WALLS - 1)


def build(values: Mapping[str, Array], key: Array) -> World:
    """A hallway world of the parameter ``values``; ``key`` jitters the spawn lattices."""
    return two_rooms(key, CAPACITY, values["room_height"], values["left_depth"],
                     values["right_depth"], values["corridor_length"],
                     values["corridor_width"], values["corridor_offset"],
                     values["layby_depth"], values["layby_at"], values["layby_length"],
                     ways=values["ways"])


HALLWAY = Family("hallway", "two rooms joined by a corridor with an optional lay-by; robots "
                 "cross both ways (or one way: ways)", PARAMETERS, CAPACITY, build)
