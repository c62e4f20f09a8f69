"""A robot's observation vector from what its sensors and navigation stack publish, laid out
as the exported actor's sidecar (``actor.json``: ``observation.terms``, each term's name,
columns, span and settings) says, computed as sgjax's observation terms compute them.

What each term reads (a :class:`RobotView`, built from ROS 2 messages by :mod:`.messages`):

========================  ====================================================================
``pose``                  own odometry: ``x, y`` (m, ``map``) and ``cos, sin`` of the heading
``velocity``              own odometry's twist (body frame; ``frame: world`` rotates it)
``goal``                  the goal (``geometry_msgs/PoseStamped``), in the robot's frame
``goal_distance``         straight-line distance to the goal (m)
``waypoint``              the next node of the route (``geometry_msgs/PointStamped`` from the
                          global planner), in the robot's frame; the goal when there is none
``lidar``                 the ``sensor_msgs/LaserScan``: per policy beam the reading nearest in
                          angle, capped at the term's ``range``
``others``                other robots (their ``nav_msgs/Odometry``, shared by the fleet) and
                          people (``people_msgs/People`` from a tracker): the ``k`` nearest
``zone_ahead``            7 values from the fleet's conflict-zone coordinator
                          (``std_msgs/Float32MultiArray``): the zone books are shared state
========================  ====================================================================

A term with ``history > 1`` keeps its past values per robot (:meth:`ObservationBuilder.start`
at an episode's start, as sgjax repeats the first value before it). Any other term, or a
setting a robot cannot honour (lidar noise is the sensor's own), is refused by name when the
builder is made, never silently dropped."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .messages import Body

SUPPORTED = ("pose", "velocity", "goal", "goal_distance", "waypoint", "lidar", "others",
             "zone_ahead")
ZONE_AHEAD_SIZE = 7


@dataclasses.dataclass
class RobotView:
    """What one robot knows at a control tick: itself, its goal and next waypoint (m, ``map``),
    its scan ``(angles [N] rad, ranges [N] m)``, the other bodies (other robots first, in fleet
    order, then people) and the zone coordinator's 7 values."""

    me: Body
    goal: tuple[float, float]
    waypoint: tuple[float, float] | None = None
    scan: tuple[np.ndarray, np.ndarray] | None = None
    others: Sequence[Body] = ()
    zone_ahead: np.ndarray | None = None


def to_robot_frame(heading: float, dx: float, dy: float) -> tuple[float, float]:
    """A world vector in the frame of a robot heading ``heading`` (x forward, y left)."""
    c, s = math.cos(heading), math.sin(heading)
    return c * dx + s * dy, -s * dx + c * dy


def beam_angles(beams: int, fov: float) -> np.ndarray:
    """The policy's beam directions (rad, robot frame), as sgjax's lidar lays them out."""
    if fov >= 2.0 * math.pi - 1e-9:
        return np.arange(beams) * (2.0 * math.pi / beams) - math.pi
    if beams == 1:
        return np.zeros(1)
    return np.linspace(-fov / 2.0, fov / 2.0, beams)


class ObservationBuilder:
    """Builds observation rows ``[D]`` (float32) for the actor described by ``sidecar`` (the
    exported ``actor.json`` as a dict)."""

    def __init__(self, sidecar: dict[str, Any]):
        layout = sidecar["observation"]
        self.size = int(layout["size"])
        self.terms: list[tuple[dict[str, Any], Callable[[int, RobotView], list[float]]]] = []
        for term in layout["terms"]:
            name, options = term["name"], term.get("options", {})
            if name not in SUPPORTED:
                raise ValueError(f"actor.json: observation term {name!r} has no robot-side "
                                 f"source in this example; supported: {list(SUPPORTED)}")
            if name == "lidar" and options.get("noise", 0.0):
                raise ValueError("actor.json: lidar noise is simulated in training; a robot's "
                                 "scan has its own (export from a run without it, or drop it)")
            reader = getattr(self, f"_{name}")
            self.terms.append((term, lambda i, view, r=reader, o=options: r(i, view, o)))
        self.past: dict[tuple[str, int], list[list[float]]] = {}

    def start(self, robot: int | None = None) -> None:
        """Forget the past values (``history > 1`` terms) of ``robot``, or of every robot: call
        at an episode's start."""
        self.past = {} if robot is None else {
            k: v for k, v in self.past.items() if k[1] != robot}

    def build(self, robot: int, view: RobotView) -> np.ndarray:
        """Robot ``robot``'s observation row ``[D]`` (float32)."""
        row = np.zeros(self.size, np.float32)
        for term, read in self.terms:
            values = read(robot, view)
            span = term["stop"] - term["start"]
            if len(values) != span:
                raise ValueError(f"term {term['name']!r}: {len(values)} values for its "
                                 f"{span} columns (actor.json and this builder disagree)")
            row[term["start"]:term["stop"]] = values
        return row

    def _with_past(self, name: str, robot: int, now: list[float], history: int
                   ) -> list[float]:
        """``now`` and the ``history - 1`` previous values, latest first (the first value
        repeated before an episode's start)."""
        past = self.past.setdefault((name, robot), [])
        if not past:
            past.extend([now] * max(history - 1, 0))
        out = [v for values in [now, *past[:history - 1]] for v in values]
        past.insert(0, now)
        del past[max(history - 1, 0):]
        return out

    def _pose(self, robot: int, view: RobotView, o: dict[str, Any]) -> list[float]:
        me = view.me
        return [me.x, me.y] + ([math.cos(me.heading), math.sin(me.heading)]
                               if o.get("heading", True) else [])

    def _velocity(self, robot: int, view: RobotView, o: dict[str, Any]) -> list[float]:
        me = view.me
        now = [me.v_forward, me.v_lateral] if o.get("frame", "body") == "body" else [me.vx,
                                                                                   me.vy]
        now += [me.omega] if o.get("turn_rate", True) else []
        return self._with_past("velocity", robot, now, int(o.get("history", 1)))

    def _goal(self, robot: int, view: RobotView, o: dict[str, Any]) -> list[float]:
        gx, gy = view.goal
        if o.get("frame", "robot") == "world":
            return [gx, gy]
        return list(to_robot_frame(view.me.heading, gx - view.me.x, gy - view.me.y))

    def _goal_distance(self, robot: int, view: RobotView, o: dict[str, Any]) -> list[float]:
        now = [math.hypot(view.goal[0] - view.me.x, view.goal[1] - view.me.y)]
        return self._with_past("goal_distance", robot, now, int(o.get("history", 1)))

    def _waypoint(self, robot: int, view: RobotView, o: dict[str, Any]) -> list[float]:
        wx, wy = view.waypoint if view.waypoint is not None else view.goal
        return list(to_robot_frame(view.me.heading, wx - view.me.x, wy - view.me.y))

    def _lidar(self, robot: int, view: RobotView, o: dict[str, Any]) -> list[float]:
        if view.scan is None:
            raise ValueError("the actor reads a lidar term: no LaserScan has arrived")
        wanted = beam_angles(int(o.get("beams", 16)), float(o.get("fov", 2.0 * math.pi)))
        angles, ranges = view.scan
        gap = np.abs((wanted[:, None] - angles[None, :] + math.pi) % (2.0 * math.pi) - math.pi)
        nearest = ranges[np.argmin(gap, axis=1)]
        return list(np.clip(nearest, 0.0, float(o.get("range", 5.0))))

    def _others(self, robot: int, view: RobotView, o: dict[str, Any]) -> list[float]:
        me = view.me
        features = o.get("features", ["position", "distance", "heading", "velocity",
                                      "radius", "kind", "mask"])
        seen = [b for b in view.others
                if (o.get("robots", True) or b.is_human) and (o.get("humans", True)
                                                               or not b.is_human)]
        limit = o.get("max_range")
        centre = [math.hypot(b.x - me.x, b.y - me.y) for b in seen]
        order = sorted(range(len(seen)), key=lambda j: centre[j])  # stable on ties
        if limit is not None:
            order = [j for j in order if centre[j] <= limit]
        k = int(o.get("k", 4))
        width = sum(FEATURE_WIDTH[f] for f in features)
        out: list[float] = []
        for j in order[:k]:
            out += _features(me, seen[j], centre[j], features, o.get("relative_velocity",
                                                                      False))
        return out + [0.0] * (width * (k - min(k, len(order))))

    def _zone_ahead(self, robot: int, view: RobotView, o: dict[str, Any]) -> list[float]:
        if view.zone_ahead is None or len(view.zone_ahead) != ZONE_AHEAD_SIZE:
            raise ValueError("the actor reads zone_ahead: it needs the fleet's conflict-zone "
                             f"coordinator's {ZONE_AHEAD_SIZE} values for this robot "
                             "(ahead, distance, priority, place, inside, entering, "
                             "entering_count)")
        return [float(v) for v in view.zone_ahead]


# columns per feature of the others term (sgjax.observations.others.FEATURES)
FEATURE_WIDTH = {"position": 2, "distance": 1, "heading": 2, "velocity": 2, "radius": 1,
                 "kind": 1, "mask": 1, "goal": 2}


def _features(me: Body, other: Body, centre: float, features: Sequence[str],
              relative_velocity: bool) -> list[float]:
    """One other body's feature columns in ``me``'s frame (sgjax's ``others`` term)."""
    c, s = math.cos(me.heading), math.sin(me.heading)
    co, so = math.cos(other.heading), math.sin(other.heading)
    vx, vy = other.vx, other.vy
    if relative_velocity:
        vx, vy = vx - me.vx, vy - me.vy
    goal = (0.0, 0.0)
    if "goal" in features and not other.is_human:
        if other.goal is None:
            raise ValueError("the actor reads the other robots' goals (others: features: "
                             "goal): the fleet must share each robot's goal")
        goal = to_robot_frame(me.heading, other.goal[0] - me.x, other.goal[1] - me.y)
    columns = {
        "position": list(to_robot_frame(me.heading, other.x - me.x, other.y - me.y)),
        "distance": [centre - other.radius - me.radius],
        "heading": [c * co + s * so, c * so - s * co],
        "velocity": list(to_robot_frame(me.heading, vx, vy)),
        "radius": [other.radius],
        "kind": [1.0 if other.is_human else 0.0],
        "mask": [1.0],
        "goal": list(goal),
    }
    return [v for name in features for v in columns[name]]
