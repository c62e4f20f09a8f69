"""Readings from ROS 2 messages, in SI units and the ``map`` frame (x forward, y left,
headings in rad counter-clockwise from +x).

Every reader takes the message object and reads fields by their ROS 2 names, so ``rclpy``
messages and ``rosbags``' dataclasses both work. Messages are expected in the ``map`` frame
(odometry's pose, goal, waypoint, people); a reader does not transform between frames (a node
that receives them in another frame transforms them first, with tf2)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np


@dataclasses.dataclass(frozen=True)
class Body:
    """A robot or a person as the policy sees it: centre ``(x, y)`` (m), ``heading`` (rad),
    world velocity ``(vx, vy)`` (m/s), ``radius`` (m), ``is_human``; for a robot its body-frame
    ``v_forward``, ``v_lateral`` (m/s), ``omega`` (rad/s) and, if known, its goal (m)."""

    x: float
    y: float
    heading: float
    vx: float
    vy: float
    radius: float
    is_human: bool
    v_forward: float = 0.0
    v_lateral: float = 0.0
    omega: float = 0.0
    goal: tuple[float, float] | None = None


def yaw(quaternion: Any) -> float:
    """The rotation about z (rad) of a ``geometry_msgs/Quaternion``."""
    q = quaternion
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def robot_from_odometry(odometry: Any, radius: float,
                        goal: tuple[float, float] | None = None) -> Body:
    """A robot from its ``nav_msgs/Odometry``: pose in ``map``, twist in its body frame (ROS's
    convention: ``child_frame_id``), as a robot's base controller publishes it."""
    pose, twist = odometry.pose.pose, odometry.twist.twist
    heading = yaw(pose.orientation)
    forward, lateral = float(twist.linear.x), float(twist.linear.y)
    c, s = math.cos(heading), math.sin(heading)
    return Body(x=float(pose.position.x), y=float(pose.position.y), heading=heading,
                vx=forward * c - lateral * s, vy=forward * s + lateral * c, radius=radius,
                is_human=False, v_forward=forward, v_lateral=lateral,
                omega=float(twist.angular.z), goal=goal)


def people_from_message(people: Any, radius: float) -> list[Body]:
    """Pedestrians from a ``people_msgs/People`` (a tracker's output: each person's position and
    velocity in ``map``); a person faces along their velocity, +x when standing (below 1 mm/s),
    as sgjax's pedestrians do."""
    bodies = []
    for person in people.people:
        vx, vy = float(person.velocity.x), float(person.velocity.y)
        moving = math.hypot(vx, vy) > 1e-3
        bodies.append(Body(x=float(person.position.x), y=float(person.position.y),
                           heading=math.atan2(vy, vx) if moving else 0.0, vx=vx, vy=vy,
                           radius=radius, is_human=True))
    return bodies


def point_of(message: Any) -> tuple[float, float]:
    """``(x, y)`` of a ``geometry_msgs/PoseStamped`` or ``PointStamped`` (in ``map``)."""
    inner = message.pose.position if hasattr(message, "pose") else message.point
    return float(inner.x), float(inner.y)


def scan_ranges(scan: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(angles, ranges)`` of a ``sensor_msgs/LaserScan`` in its frame (rad, m); readings
    outside ``[range_min, range_max]`` (no return, NaN) read ``inf``."""
    ranges = np.asarray(scan.ranges, np.float64)
    angles = scan.angle_min + scan.angle_increment * np.arange(len(ranges))
    valid = np.isfinite(ranges) & (ranges >= scan.range_min) & (ranges <= scan.range_max)
    return angles, np.where(valid, ranges, np.inf)


def values_of(array_message: Any) -> np.ndarray:
    """The values of a ``std_msgs/Float32MultiArray`` as a float array."""
    return np.asarray(array_message.data, np.float64)
