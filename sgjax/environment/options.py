"""The options of :func:`sgjax.make`, typed and grouped, validated in one place.

``make(scenario, **keywords)`` takes flat keywords (``num_agents=4, human_model="helbing"``);
each belongs to one group:

* :class:`RobotOptions`: ``num_agents``, ``min_agents``, ``max_agents``, ``robots``,
  ``action_mode``, ``decision_period``, ``goal_tolerance``, ``arrived``, ``ended``;
* :class:`HumanOptions`: ``num_humans``, ``max_humans``, ``human_model``, ``human_walls``,
  ``human_goals``, ``human_radius``, ``humans_see_robots``, ``human_groups``;
* :class:`TermOptions`: ``observations``, ``rewards``, ``enders``, ``terms``,
  ``observation_preset``, ``reward_preset`` (``docs/terms.md``);
* :class:`PhysicsOptions`: ``dt``, ``substeps``, ``time_limit``, ``num_arcs``,
  ``contact_passes``.

:class:`MakeOptions` holds the four groups; ``MakeOptions.from_keywords(**kw)`` builds it from
flat keywords (an unknown one names the nearest valid keyword), ``options.keywords()`` gives them
back, and ``make(scenario, options=...)`` takes it whole. The trainer's ``env`` config section
takes the same keywords (``train/config.py``). Bad values raise ``ValueError`` naming the keyword.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from sgjax.dynamics.limits import RobotPreset
from sgjax.humans.groups import leaders
from sgjax.humans.pedestrians import FORCE_MODELS, GOAL_MODES, WALL_MODELS, HumanConfig
from sgjax.terms.base import suggest
from sgjax.types import ACTION_MODES, ARRIVED_SEMANTICS, WORLD_SEMANTICS


def _positive_int(name: str, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")


def _count(name: str, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
        raise ValueError(f"{name} must be a non-negative integer, got {value!r}")


def _within_slots(name: str, value: Any, slots_name: str, slots: Any,
                  check: Callable[[str, Any], None]) -> None:
    """``value`` and ``slots`` (when given) pass ``check``, and ``value <= slots``."""
    check(name, value)
    if slots is not None:
        check(slots_name, slots)
        if value > slots:
            raise ValueError(f"{name} ({value}) must not exceed {slots_name} ({slots})")


def _positive_float(name: str, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating) or not (
        math.isfinite(value) and value > 0
    ):
        raise ValueError(f"{name} must be a positive number, got {value!r}")


def _choice(name: str, value: Any, choices: tuple[str, ...]) -> None:
    if value not in choices:
        hint = suggest(value, list(choices)) if isinstance(value, str) else ""
        raise ValueError(f"{name} must be one of {choices}, got {value!r}{hint}")


@dataclasses.dataclass(frozen=True)
class RobotOptions:
    """Who drives: how many robots, which kinds, how they act and when they have arrived."""

    num_agents: int = 4  # robots in an episode (a param: change it without recompiling)
    min_agents: int | None = None  # draw each episode's count from [min_agents, num_agents]
    max_agents: int | None = None  # robot slots R (static); default: num_agents
    robots: Any = "socialgym"  # preset name, RobotPreset, or a list (one per slot, cycled)
    action_mode: str = "go_stop"  # or "continuous"
    # Steps each action is held: robots read a new action at the steps whose episode time is
    # a multiple of it (1: every step); in between each keeps its last one.
    decision_period: int = 1
    goal_tolerance: float = 0.5  # m (SocialGym's success radius)
    # An arrived robot is driven on to its goal point by its planner and parks there ("settle",
    # as SocialGym 2.0 ran), stays where it arrived as a static body ("park"), or will "leave".
    arrived: str = "settle"
    ended: str = "leave"  # the same for a robot an ender terminates (e.g. a fatal collision)

    def __post_init__(self) -> None:
        _within_slots("num_agents", self.num_agents, "max_agents", self.max_agents,
                      _positive_int)
        if self.min_agents is not None:
            _within_slots("min_agents", self.min_agents, "num_agents", self.num_agents,
                          _positive_int)
        _choice("action_mode", self.action_mode, ACTION_MODES)
        _positive_int("decision_period", self.decision_period)
        _positive_float("goal_tolerance", self.goal_tolerance)
        _choice("arrived", self.arrived, ARRIVED_SEMANTICS)
        _choice("ended", self.ended, WORLD_SEMANTICS)
        if not isinstance(self.robots, str | RobotPreset | list | tuple):
            raise ValueError(f"robots must be a preset name, a RobotPreset or a list of them, "
                             f"got {self.robots!r}")

    @property
    def slots(self) -> int:
        """Robot slots ``R``."""
        return self.num_agents if self.max_agents is None else self.max_agents


@dataclasses.dataclass(frozen=True)
class HumanOptions:
    """Pedestrians: how many, which social-force law, how they see walls and pick goals."""

    num_humans: int = 0  # pedestrians in an episode (a param: change it without recompiling)
    max_humans: int | None = None  # pedestrian slots H (static); default: num_humans
    human_model: str = "moussaid"  # "moussaid" or "helbing" (social forces), "orca", "hsfm"
    human_walls: str = "segments"  # Moussaid wall term: "segments" or "points" (PySocialForce)
    human_goals: str = "random"  # at its goal a pedestrian takes a "random" node or will "return"
    human_radius: float = 0.25  # m (SocialGym 0.2, CrowdNav 0.3, PySocialForce 0.35)
    # Pedestrians react to robots (True), or walk as if robots were not there (False, the robot
    # CrowdNav's published results use): their force law or ORCA ignores robots; bodies still
    # do not pass through each other.
    humans_see_robots: bool = True
    # Group sizes: the first pedestrians walk in groups of these sizes (spawned together, one
    # goal, Moussaid 2010 group forces); the rest alone. A param: no recompilation.
    human_groups: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.humans_see_robots, bool):
            raise ValueError(f"humans_see_robots must be True or False, got "
                             f"{self.humans_see_robots!r}")
        _within_slots("num_humans", self.num_humans, "max_humans", self.max_humans, _count)
        _positive_float("human_radius", self.human_radius)
        _choice("human_model", self.human_model, FORCE_MODELS)
        _choice("human_walls", self.human_walls, WALL_MODELS)
        _choice("human_goals", self.human_goals, GOAL_MODES)
        if not isinstance(self.human_groups, list | tuple):
            raise ValueError(f"human_groups must be a list of group sizes, got "
                             f"{self.human_groups!r}")
        object.__setattr__(self, "human_groups", tuple(self.human_groups))
        leaders(self.human_groups, self.slots)  # sizes >= 1, all within max_humans

    @property
    def slots(self) -> int:
        """Pedestrian slots ``H``."""
        return self.num_humans if self.max_humans is None else self.max_humans

    def config(self) -> HumanConfig:
        """The static pedestrian settings of the environment."""
        return HumanConfig(max_humans=self.slots, force_model=self.human_model,
                           wall_model=self.human_walls, goal_mode=self.human_goals)


@dataclasses.dataclass(frozen=True)
class TermOptions:
    """Observation, reward and ender terms: each a preset name, a spec (list / mapping) or a
    YAML/JSON path; ``terms`` is a mapping or file with any of the three sections. ``None``
    takes the ``default`` presets (the reward preset brings its enders)."""

    observations: Any = None
    rewards: Any = None
    enders: Any = None
    terms: Any = None
    observation_preset: str | None = None  # same as observations=<name>
    reward_preset: str | None = None  # same as rewards=<name>

    def __post_init__(self) -> None:
        for name, preset in (("observations", "observation_preset"),
                             ("rewards", "reward_preset")):
            value = getattr(self, preset)
            if value is None:
                continue
            if getattr(self, name) is not None:
                raise ValueError(f"give {name}= or {preset}=, not both")
            if not isinstance(value, str):
                raise ValueError(f"{preset} must be a preset name, got {value!r}")

    @property
    def resolved_observations(self) -> Any:
        """``observations``, or the preset that ``observation_preset`` names."""
        return self.observation_preset or self.observations

    @property
    def resolved_rewards(self) -> Any:
        """``rewards``, or the preset that ``reward_preset`` names."""
        return self.reward_preset or self.rewards


@dataclasses.dataclass(frozen=True)
class PhysicsOptions:
    """Time: the step, its sub-steps, the episode's length, and the local planner's arcs."""

    dt: float = 0.1  # s per step
    substeps: int | None = None  # integration sub-steps per step; default: the fewest safe
    time_limit: float = 75.0  # s before truncation (SocialGym: 3000 steps x 0.025 s)
    num_arcs: int = 11  # local planner arcs (SocialGym sampled 41; see bench/ for the cost)
    contact_passes: int = 1  # robot-robot separation passes per sub-step (more: less overlap)

    def __post_init__(self) -> None:
        _positive_float("dt", self.dt)
        if self.substeps is not None:
            _positive_int("substeps", self.substeps)
        _positive_float("time_limit", self.time_limit)
        _positive_int("num_arcs", self.num_arcs)
        _positive_int("contact_passes", self.contact_passes)

    @property
    def max_steps(self) -> int:
        """Steps before truncation: ``ceil(time_limit / dt)``."""
        return math.ceil(self.time_limit / self.dt - 1e-9)


GROUPS: dict[str, type] = {"robots": RobotOptions, "humans": HumanOptions,
                           "terms": TermOptions, "physics": PhysicsOptions}
# Flat keyword -> its group.
KEYWORDS: dict[str, str] = {f.name: group for group, cls in GROUPS.items()
                            for f in dataclasses.fields(cls)}


@dataclasses.dataclass(frozen=True)
class MakeOptions:
    """Every option of :func:`sgjax.make`, in four groups."""

    robots: RobotOptions = dataclasses.field(default_factory=RobotOptions)
    humans: HumanOptions = dataclasses.field(default_factory=HumanOptions)
    terms: TermOptions = dataclasses.field(default_factory=TermOptions)
    physics: PhysicsOptions = dataclasses.field(default_factory=PhysicsOptions)

    @classmethod
    def from_keywords(cls, where: str = "make", **keywords: Any) -> MakeOptions:
        """Options from flat keywords; the rest keep their defaults."""
        return cls().replace(where=where, **keywords)

    def replace(self, where: str = "make", **keywords: Any) -> MakeOptions:
        """These options with some flat keywords changed (validated again)."""
        check_keywords(where, keywords)
        changed = {}
        for group in GROUPS:
            mine = {k: v for k, v in keywords.items() if KEYWORDS[k] == group}
            if mine:
                changed[group] = dataclasses.replace(getattr(self, group), **mine)
        return dataclasses.replace(self, **changed)

    def keywords(self, changed_only: bool = False) -> dict[str, Any]:
        """The flat keywords (only those that differ from the defaults, with
        ``changed_only``)."""
        out = {}
        for group in GROUPS:
            values, defaults = getattr(self, group), GROUPS[group]()
            for f in dataclasses.fields(values):
                value = getattr(values, f.name)
                if not changed_only or value != getattr(defaults, f.name):
                    out[f.name] = value
        return out


def check_keywords(where: str, keywords: Any) -> None:
    """Raise ``TypeError`` naming the nearest valid keyword for any unknown one."""
    for key in keywords:
        if key not in KEYWORDS:
            raise TypeError(f"{where}: unknown option {key!r}{suggest(str(key), list(KEYWORDS))}"
                            f"; valid options are: {', '.join(KEYWORDS)}")
