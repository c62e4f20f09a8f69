"""Robot dynamics: limits, presets and the kinematic integrator."""

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
