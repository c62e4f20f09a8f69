"""Robot dynamics: limits, presets, the kinematic integrator (``limits``, ``models``) and
SocialGym 2.0's local planner that drives a robot along its route (``planner``)."""

from sgjax.dynamics.limits import (
    ACKERMANN,
    DIFF_DRIVE,
    OMNIDIRECTIONAL,
    PRESETS,
    RobotParams,
    RobotPreset,
    resolve_robots,
    robot_params,
)
from sgjax.dynamics.models import (
    Kinematics,
    clip_command,
    decode_continuous,
    integrate,
    stop_on_contact,
)

__all__ = [
    "ACKERMANN",
    "DIFF_DRIVE",
    "OMNIDIRECTIONAL",
    "PRESETS",
    "Kinematics",
    "RobotParams",
    "RobotPreset",
    "clip_command",
    "decode_continuous",
    "integrate",
    "resolve_robots",
    "robot_params",
    "stop_on_contact",
]
