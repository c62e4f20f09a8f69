"""The crowd-navigation scenarios of CrowdNav and social-jym as generated maps: open arenas
whose route groups place robots and pedestrians (``sgjax.make("circle_crossing")``; every name
in :data:`CROWD_SCENARIOS` is listed by ``sgjax.registered()``).

Each is an open square arena (walls ``margin`` m outside the routes), a navigation graph whose
every pair of nodes in view is joined (so every route is a straight line), route groups for the
robots (``groups``) and for the pedestrians (``pedestrian_groups``, walked back and forth by
``human_goals="routes"``, which ``make`` picks for these scenarios). Sizes in metres:

* ``circle_crossing(radius=4, points=24)``: everybody starts on a circle and heads for the
  opposite point (CrowdNav's circle crossing, radius 4 m);
* ``square_crossing(side=10, points=6)``: from points on the west and east sides of a square
  to any point on the opposite side (CrowdNav's square crossing, 10 m);
* ``parallel_traffic(length=12, width=4, lanes=4)``: two-way traffic along a ``width`` m wide
  band, robots and pedestrians alike (social-jym's parallel traffic);
* ``perpendicular_traffic(length=12, width=4, lanes=4)``: robots cross the arena west to east
  (and back) while pedestrians walk across their way, south to north and back (social-jym's
  perpendicular traffic).

The sampled episode (which route each robot and pedestrian takes, the pedestrians' desired
speeds and count) is drawn inside ``reset``. Counts and speeds are params (``num_agents``,
``params.humans.num_humans``, ``params.humans.speed_*``, ``params.robots``); so is the size:
:func:`resize` scales the routes (circle radius, square side, band length and width) by a
traced factor in ``(0, 1]`` of the size given to the generator, which sets the arena walls
(``make(circle_crossing(radius=8))`` then ``resize(params.map, r / 8)`` sweeps radii ``r`` up to
8 m in one compiled function).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import jax
import jax.numpy as jnp
from jax import Array

from sgjax.maps.arrays import MapArrays
from sgjax.maps.schema import MapSpec, parse_map

MARGIN = 2.0  # m: from the outermost route node to the arena wall


def _arena(name: str, description: str, points: list[tuple[float, float]],
           groups: list[tuple[list[int], list[int]]],
           pedestrian_groups: list[tuple[list[int], list[int]]] | None = None,
           margin: float = MARGIN) -> MapSpec:
    reach = max(max(abs(x), abs(y)) for x, y in points) + margin
    walls = [[-reach, -reach, reach, -reach], [reach, -reach, reach, reach],
             [reach, reach, -reach, reach], [-reach, reach, -reach, -reach]]
    nodes = [{"id": i, "position": [round(x, 6), round(y, 6)]} for i, (x, y) in enumerate(points)]
    edges = [[a, b] for a in range(len(points)) for b in range(a + 1, len(points))]

    def listed(pairs):
        return [{"starts": starts, "goals": goals} for starts, goals in pairs]

    data = {"name": name, "description": description,
            "bounds": [-reach - 0.5, -reach - 0.5, reach + 0.5, reach + 0.5],
            "walls": walls, "nodes": nodes, "edges": edges, "groups": listed(groups)}
    if pedestrian_groups:
        data["pedestrian_groups"] = listed(pedestrian_groups)
    return parse_map(data, source=f"sgjax.maps.crowd_scenarios.{name}")


def circle_crossing(radius: float = 4.0, points: int = 24) -> MapSpec:
    """Starts on a circle of ``radius`` m, every start bound for its opposite point."""
    if radius <= 0 or points < 2 or points % 2:
        raise ValueError(f"circle_crossing: radius must be > 0 and points an even number >= 2, "
                         f"got radius={radius}, points={points}")
    xy = [(radius * math.cos(2 * math.pi * i / points), radius * math.sin(2 * math.pi * i / points))
          for i in range(points)]
    pairs = [([i], [(i + points // 2) % points]) for i in range(points)]
    return _arena("circle_crossing", f"circle crossing, radius {radius:g} m: everybody heads "
                  "for the opposite point of the circle", xy, pairs)


def square_crossing(side: float = 10.0, points: int = 6) -> MapSpec:
    """Starts on the west and east sides of a ``side`` m square, goals anywhere on the
    opposite side."""
    if side <= 0 or points < 1:
        raise ValueError(f"square_crossing: side must be > 0 and points >= 1, got side={side}, "
                         f"points={points}")
    half = side / 2
    ys = [half * (2 * (k + 0.5) / points - 1) for k in range(points)]
    west = [(-half, y) for y in ys]
    east = [(half, y) for y in ys]
    west_rows = list(range(points))
    east_rows = list(range(points, 2 * points))
    pairs = [(west_rows, east_rows), (east_rows, west_rows)]
    return _arena("square_crossing", f"square crossing, {side:g} m: from one side of the square "
                  "to any point of the opposite side", west + east, pairs)


def _lanes(width: float, lanes: int) -> list[float]:
    return [width * ((k + 0.5) / lanes - 0.5) for k in range(lanes)]


def parallel_traffic(length: float = 12.0, width: float = 4.0, lanes: int = 4) -> MapSpec:
    """Two-way traffic along a ``width`` m band, ``length`` m long: robots and pedestrians."""
    if length <= 0 or width <= 0 or lanes < 1:
        raise ValueError(f"parallel_traffic: length and width must be > 0 and lanes >= 1, got "
                         f"{length}, {width}, {lanes}")
    half = length / 2
    west = [(-half, y) for y in _lanes(width, lanes)]
    east = [(half, y) for y in _lanes(width, lanes)]
    pairs = [([k], [lanes + k]) for k in range(lanes)] + [([lanes + k], [k])
                                                         for k in range(lanes)]
    return _arena("parallel_traffic", f"parallel traffic: two-way along a {width:g} m band, "
                  f"{length:g} m long", west + east, pairs)


def perpendicular_traffic(length: float = 12.0, width: float = 4.0, lanes: int = 4) -> MapSpec:
    """Robots west to east and back along a ``width`` m band; pedestrians south to north and
    back across it."""
    if length <= 0 or width <= 0 or lanes < 1:
        raise ValueError(f"perpendicular_traffic: length and width must be > 0 and lanes >= 1, "
                         f"got {length}, {width}, {lanes}")
    half = length / 2
    band = _lanes(width, lanes)
    west = [(-half, y) for y in band]
    east = [(half, y) for y in band]
    south = [(x, -half) for x in band]
    north = [(x, half) for x in band]
    w, e = list(range(lanes)), list(range(lanes, 2 * lanes))
    s, n = list(range(2 * lanes, 3 * lanes)), list(range(3 * lanes, 4 * lanes))
    robots = [([w[k]], [e[k]]) for k in range(lanes)] + [([e[k]], [w[k]]) for k in range(lanes)]
    people = [([s[k]], [n[k]]) for k in range(lanes)] + [([n[k]], [s[k]]) for k in range(lanes)]
    return _arena("perpendicular_traffic", "perpendicular traffic: robots cross west-east, "
                  "pedestrians south-north across their way", west + east + south + north,
                  robots, people)


def resize(m: MapArrays, scale: float | Array) -> MapArrays:
    """A crowd scenario's map with its routes scaled by ``scale`` about the arena's centre.

    ``m`` is a crowd scenario's ``params.map`` (centred on the origin; its walls stay where the
    generator put them, so the generator's size is the largest and ``scale`` is in ``(0, 1]``);
    ``scale`` is a scalar, possibly traced: ``jax.vmap`` over it is a sweep over circle radii,
    square sides or traffic bands in one compiled function. Scaled: node positions (m), the
    shortest-path lengths (m, every route here is a straight line, so the next hops do not
    change) and the node gaps (m). Robot starts, goals and routes and the pedestrians' routes
    follow the nodes; pedestrians still start on the free spawn slot nearest their route's
    start (the slots cover the arena). A concrete ``scale`` outside ``(0, 1]`` is a
    ``ValueError``; a traced one is not checked.
    """
    if not isinstance(scale, jax.core.Tracer):
        value = float(scale)
        if not 0.0 < value <= 1.0:
            raise ValueError(f"crowd.resize: scale must be in (0, 1] (the generator's size is "
                             f"the largest; the arena walls stay), got {value}")
    scale = jnp.asarray(scale, jnp.float32)
    return m.replace(
        node_x=m.node_x * scale,
        node_y=m.node_y * scale,
        path_length=jnp.where(m.path_length >= 0.0, m.path_length * scale, m.path_length),
        node_gap=m.node_gap * scale,
    )


CROWD_SCENARIOS: dict[str, Callable[[], MapSpec]] = {
    "circle_crossing": circle_crossing,
    "square_crossing": square_crossing,
    "parallel_traffic": parallel_traffic,
    "perpendicular_traffic": perpendicular_traffic,
}
