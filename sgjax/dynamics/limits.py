"""Per-robot kinodynamic limits (``RobotParams``) and named presets with their sources."""

from __future__ import annotations

import dataclasses
import math

import jax.numpy as jnp
from flax import struct
from jax import Array

DIFF_DRIVE, OMNIDIRECTIONAL, ACKERMANN = 0, 1, 2
MODEL_NAMES = {"diff_drive": DIFF_DRIVE, "omnidirectional": OMNIDIRECTIONAL, "ackermann": ACKERMANN}


@struct.dataclass
class RobotParams:
    """Limits of every robot slot, each ``[R]`` (SI units: m, m/s, m/s^2, rad/s, rad/s^2).

    ``model`` is 0 diff drive, 1 omnidirectional, 2 Ackermann. ``wheelbase``,
    ``min_turn_radius`` and ``max_steer_rate`` (rad/s) matter only for Ackermann robots.
    """

    model: Array
    radius: Array
    max_speed: Array
    max_reverse_speed: Array
    max_accel: Array
    max_decel: Array
    max_omega: Array
    max_alpha: Array
    wheelbase: Array
    min_turn_radius: Array
    max_steer_rate: Array

    @property
    def max_steering(self) -> Array:
        """Largest steering angle (rad) allowed by the minimum turning radius."""
        return jnp.arctan(self.wheelbase / self.min_turn_radius)


@dataclasses.dataclass(frozen=True)
class RobotPreset:
    """One robot type's limits; ``source`` says where the numbers come from."""

    model: str
    radius: float
    max_speed: float
    max_reverse_speed: float
    max_accel: float
    max_decel: float
    max_omega: float
    max_alpha: float
    wheelbase: float = 0.0
    min_turn_radius: float = 0.0
    max_steer_rate: float = 0.0
    source: str = ""

    def validate(self, name: str) -> None:
        """Raise ``ValueError`` naming the preset and field of an impossible robot."""
        if self.model not in MODEL_NAMES:
            raise ValueError(f"robot {name!r}: model {self.model!r} is not one of "
                             f"{list(MODEL_NAMES)}")
        positive = ["radius", "max_speed", "max_accel", "max_decel", "max_omega", "max_alpha"]
        if self.model == "ackermann":
            positive += ["wheelbase", "min_turn_radius", "max_steer_rate"]
        for field in positive:
            value = getattr(self, field)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"robot {name!r}: {field} must be a positive number, got {value}")
        if not (math.isfinite(self.max_reverse_speed) and self.max_reverse_speed >= 0.0):
            raise ValueError(f"robot {name!r}: max_reverse_speed must be >= 0, "
                             f"got {self.max_reverse_speed}")


PRESETS: dict[str, RobotPreset] = {
    "socialgym": RobotPreset(
        "diff_drive", radius=0.2, max_speed=1.5, max_reverse_speed=0.0, max_accel=5.0,
        max_decel=5.0, max_omega=3.0, max_alpha=5.0,
        source="SocialGym 2.0's effective limits: planner caps 1.5 m/s and 5 m/s^2, the Jackal "
               "model clamps omega to 3 rad/s, planner angular accel 5 rad/s^2; radius 0.2 m from "
               "its 0.4 m centre-distance collision test; forward only like its planner "
               "(socialgym2.md §1.3, §5)",
    ),
    "jackal": RobotPreset(
        "diff_drive", radius=0.267, max_speed=2.0, max_reverse_speed=2.0, max_accel=3.0,
        max_decel=3.0, max_omega=3.0, max_alpha=3.0,
        source="Clearpath Jackal in ut_multirobot_sim config/ut_jackal_config.lua (2.0 m/s, "
               "3 m/s^2, "
               "3 rad/s, 3 rad/s^2); radius 0.267 m as in Arena-Rosnav (socialnav.md §D2)",
    ),
    "turtlebot3": RobotPreset(
        "diff_drive", radius=0.113, max_speed=0.22, max_reverse_speed=0.22, max_accel=2.5,
        max_decel=2.5, max_omega=2.84, max_alpha=3.2,
        source="TurtleBot3 Burger dwa_local_planner_params_burger.yaml; radius from Arena-Rosnav "
               "(socialnav.md §D2)",
    ),
    "cobot": RobotPreset(
        "omnidirectional", radius=0.2, max_speed=1.2, max_reverse_speed=1.2, max_accel=3.0,
        max_decel=3.0, max_omega=math.pi, max_alpha=math.pi,
        source="UT Cobot omni, ut_multirobot_sim config/cobot_config.lua (socialnav.md §D2)",
    ),
    "automata": RobotPreset(
        "ackermann", radius=0.302, max_speed=1.2, max_reverse_speed=1.2, max_accel=3.0,
        max_decel=3.0, max_omega=1.2 / 0.98, max_alpha=10.0, wheelbase=0.324,
        min_turn_radius=0.98, max_steer_rate=4.0,
        source="UT AUTOmata 1/10 car, ut_multirobot_sim config/ut_automata_config.lua (1.2 m/s, "
               "3 m/s^2, minimum turning radius 0.98 m); radius = half the 0.535 x 0.281 m "
               "footprint's diagonal; wheelbase 0.324 m and steering rate 4 rad/s are our "
               "assumptions (not in the config); yaw-rate cap = max speed / minimum radius",
    ),
}


def resolve_robots(
    robots: str | RobotPreset | list, max_agents: int
) -> list[tuple[str, RobotPreset]]:
    """Expand a preset name, a preset, or a list of either (one per slot, cycled) to
    ``max_agents`` named presets."""
    items = robots if isinstance(robots, list | tuple) else [robots]
    if not items:
        raise ValueError("robots: expected a preset name, a RobotPreset or a non-empty list "
                         "of them")
    named = []
    for i, item in enumerate(items):
        if isinstance(item, str):
            if item not in PRESETS:
                raise ValueError(f"robots[{i}]: unknown robot preset {item!r}; "
                                 f"presets are: {', '.join(PRESETS)}")
            named.append((item, PRESETS[item]))
        elif isinstance(item, RobotPreset):
            named.append((f"robots[{i}]", item))
        else:
            raise TypeError(f"robots[{i}]: expected a preset name or RobotPreset, got {type(item)}")
    for name, preset in named:
        preset.validate(name)
    return [named[i % len(named)] for i in range(max_agents)]


def robot_params(presets: list[RobotPreset]) -> RobotParams:
    """Stack one preset per robot slot into ``RobotParams`` arrays ``[R]``."""
    def column(field: str) -> Array:
        return jnp.asarray([getattr(p, field) for p in presets], jnp.float32)

    return RobotParams(
        model=jnp.asarray([MODEL_NAMES[p.model] for p in presets], jnp.int32),
        radius=column("radius"),
        max_speed=column("max_speed"),
        max_reverse_speed=column("max_reverse_speed"),
        max_accel=column("max_accel"),
        max_decel=column("max_decel"),
        max_omega=column("max_omega"),
        max_alpha=column("max_alpha"),
        wheelbase=jnp.asarray([p.wheelbase or 1.0 for p in presets], jnp.float32),
        min_turn_radius=jnp.asarray([p.min_turn_radius or 1.0 for p in presets], jnp.float32),
        max_steer_rate=jnp.asarray([p.max_steer_rate or 1.0 for p in presets], jnp.float32),
    )
