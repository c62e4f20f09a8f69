"""The fleet's latest messages and one control tick: observations for every robot, one call of
the actor, a velocity command per robot. Free of ROS: :mod:`.node` feeds it from ``rclpy``
subscriptions, the tests from ``rosbags`` messages."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from . import messages
from .actor import OnnxPolicy
from .commands import STOPPED, Twist3, command
from .observation import ObservationBuilder, RobotView


class FleetController:
    """Robots ``names`` (in the order of the actor's robot slots) driven by the ONNX actor
    ``model``. Call the ``on_*`` methods as messages arrive and :meth:`tick` at the control
    rate (the sidecar's ``observation.dt``); :meth:`start` at each episode's (task's) start."""

    def __init__(self, model: str | Path, names: list[str]):
        self.policy = OnnxPolicy(model)
        sidecar = self.policy.sidecar
        if len(names) > len(sidecar["robots"]):
            raise ValueError(f"{len(names)} robots, but the actor was exported with "
                             f"{len(sidecar['robots'])} robot slots")
        if len(set(names)) != len(names):
            raise ValueError(f"robot names must be distinct, got {names}")
        self.names, self.sidecar = list(names), sidecar
        self.builder = ObservationBuilder(sidecar)
        self.human_radius = float(sidecar["humans"]["radius"])
        self.latest: dict[str, dict[str, Any]] = {name: {} for name in names}
        self.people: list[messages.Body] = []

    @property
    def dt(self) -> float:
        """The control period the actor was trained at (s)."""
        return float(self.sidecar["observation"]["dt"])

    def start(self) -> None:
        """An episode starts: the actor's memory and the observation history cleared."""
        self.policy.start()
        self.builder.start()

    def _radius(self, name: str) -> float:
        return float(self.sidecar["robots"][self.names.index(name)]["radius"])

    def on_odometry(self, name: str, msg: Any) -> None:
        self.latest[name]["odometry"] = msg

    def on_goal(self, name: str, msg: Any) -> None:
        self.latest[name]["goal"] = messages.point_of(msg)

    def on_waypoint(self, name: str, msg: Any) -> None:
        self.latest[name]["waypoint"] = messages.point_of(msg)

    def on_scan(self, name: str, msg: Any) -> None:
        self.latest[name]["scan"] = messages.scan_ranges(msg)

    def on_zone_ahead(self, name: str, msg: Any) -> None:
        self.latest[name]["zone_ahead"] = messages.values_of(msg)

    def on_planner(self, name: str, msg: Any) -> None:
        self.latest[name]["planner"] = (float(msg.linear.x), float(msg.linear.y),
                                        float(msg.angular.z))

    def on_people(self, msg: Any) -> None:
        self.people = messages.people_from_message(msg, self.human_radius)

    def ready(self, name: str) -> bool:
        """Whether ``name`` has its odometry and goal (the least a policy needs)."""
        return "odometry" in self.latest[name] and "goal" in self.latest[name]

    def _body(self, name: str) -> messages.Body:
        latest = self.latest[name]
        return messages.robot_from_odometry(latest["odometry"], self._radius(name),
                                            latest.get("goal"))

    def views(self) -> list[RobotView | None]:
        """Each robot's :class:`RobotView` (None while it is not :meth:`ready`)."""
        bodies = {name: self._body(name) for name in self.names if self.ready(name)}
        out: list[RobotView | None] = []
        for name in self.names:
            if name not in bodies:
                out.append(None)
                continue
            latest = self.latest[name]
            others = [bodies[n] for n in self.names if n != name and n in bodies]
            out.append(RobotView(me=bodies[name], goal=latest["goal"],
                                 waypoint=latest.get("waypoint"), scan=latest.get("scan"),
                                 others=others + self.people,
                                 zone_ahead=latest.get("zone_ahead")))
        return out

    def observations(self) -> np.ndarray:
        """``[robots, D]``: each ready robot's observation row, zeros for the others."""
        rows = np.zeros((len(self.names), self.builder.size), np.float32)
        for i, view in enumerate(self.views()):
            if view is not None:
                rows[i] = self.builder.build(i, view)
        return rows

    def tick(self) -> tuple[np.ndarray, dict[str, Twist3]]:
        """One control step: ``(actions, {name: command})``; a robot that is not ready is
        commanded to stand still."""
        actions = self.policy.decide(self.observations())
        commands = {}
        for i, name in enumerate(self.names):
            if not self.ready(name):
                commands[name] = STOPPED
                continue
            commands[name] = command(actions[i], self.sidecar["robots"][i],
                                     self.policy.discrete, self.latest[name].get("planner"))
        return actions, commands
