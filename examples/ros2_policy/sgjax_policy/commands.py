"""Actions to velocity commands (``geometry_msgs/Twist``'s ``linear.x``, ``linear.y``,
``angular.z``: m/s, m/s, rad/s in the robot's frame).

GO/STOP (SocialGym 2.0's action): GO passes on the robot's local planner's command (its own
``cmd_vel``, as the simulated planner drives a GO robot toward its next waypoint), STOP
commands zero (the base controller brakes within its limits, as a simulated STOP brakes).
Continuous actions in [-1, 1] scale by the robot's limits as sgjax decodes them: forward by
``max_speed`` (``max_reverse_speed`` backwards), lateral by ``max_speed`` (omnidirectional
robots, three actions), turn by ``max_omega``; an Ackermann robot's turn is a steering angle
(``max_steering``), sent as the yaw rate ``v tan(steering) / wheelbase``."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .actor import GO

Twist3 = tuple[float, float, float]  # (linear.x, linear.y, angular.z)
STOPPED: Twist3 = (0.0, 0.0, 0.0)


def go_stop_command(action: int, planner: Twist3 | None) -> Twist3:
    """The command for a GO/STOP ``action`` given the local planner's latest ``planner``
    command (None when none has arrived: the robot holds still)."""
    if int(action) == GO:
        return planner if planner is not None else STOPPED
    return STOPPED


def continuous_command(action: np.ndarray, limits: dict[str, Any]) -> Twist3:
    """The command for a continuous ``action [A]`` of a robot with ``limits`` (one entry of
    the sidecar's ``robots``)."""
    a = np.clip(np.asarray(action, np.float64), -1.0, 1.0)
    f = float(a[0])
    forward = f * (limits["max_speed"] if f >= 0.0 else limits["max_reverse_speed"])
    lateral = (float(a[1]) * limits["max_speed"]
               if len(a) == 3 and limits["model"] == "omnidirectional" else 0.0)
    if limits["model"] == "ackermann":
        steering = float(a[-1]) * limits["max_steering"]
        return forward, 0.0, forward * math.tan(steering) / limits["wheelbase"]
    return forward, lateral, float(a[-1]) * limits["max_omega"]


def command(action: Any, limits: dict[str, Any], discrete: bool,
            planner: Twist3 | None = None) -> Twist3:
    """One robot's command from its action (see the module doc)."""
    return go_stop_command(action, planner) if discrete else continuous_command(action, limits)
