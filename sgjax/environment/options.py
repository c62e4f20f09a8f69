"""The options of :func:`sgjax.make`, typed and grouped, validated in one place.

``make(scenario, **keywords)`` takes flat keywords (``num_agents=4, human_model="helbing"``);
each belongs to one group:

* :class:`RobotOptions`: ``num_agents``, ``min_agents``, ``max_agents``, ``robots``,
  ``action_mode``, ``decision_period``, ``goal_tolerance``, ``arrived``, ``ended``;
* :class:`HumanOptions`: ``num_humans``, ``max_humans``, ``human_model``, ``human_walls``,
  ``human_goals``, ``human_radius``, ``humans_see_robots``, ``human_groups``, ``human_range``,
  ``human_search``, ``human_cell_capacity``;
* :class:`TermOptions`: ``observations``, ``rewards``, ``enders``, ``terms``,
  ``observation_preset``, ``reward_preset`` (``docs/terms.md``);
* :class:`PhysicsOptions`: ``dt``, ``substeps``, ``time_limit``, ``num_arcs``,
  ``contact_passes``;
* :class:`WorldOptions`: ``world_ranges``, ``world_proposals``, ``world_seeds``, ``world_levels``,
  ``world_holdout`` (generated worlds:
  ``make("generated:<family>")``, ``docs/generated.md``).

:class:`MakeOptions` holds the five groups; ``MakeOptions.from_keywords(**kw)`` builds it from
flat keywords (an unknown one names the nearest valid keyword), ``options.keywords()`` gives them
back, ``options.to_dict()`` / ``MakeOptions.from_dict`` write and read the nested form (what a
training checkpoint stores), and ``make(scenario, options=...)`` takes it whole. The trainer's
``env`` config section takes the same keywords (``train/algorithm/config.py``) and hands a
``MakeOptions`` on. Bad values raise ``ValueError`` naming the keyword and the value
(``sgjax.validation``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

from sgjax.dynamics.limits import RobotPreset
from sgjax.humans.calibrated import CONSTANT_SETS, fitted_constants
from sgjax.humans.groups import leaders
from sgjax.humans.neighbors import SEARCHES
from sgjax.humans.pedestrians import FORCE_MODELS, GOAL_MODES, WALL_MODELS, HumanConfig
from sgjax.humans.replay import REPLAY_MODES
from sgjax.types import ACTION_MODES, ARRIVED_SEMANTICS, WORLD_SEMANTICS
from sgjax.validation import (
    check_bool,
    check_choice,
    check_int,
    check_keys,
    check_positive,
    thaw,
)


def _within_slots(name: str, value: Any, slots_name: str, slots: Any, low: int) -> None:
    """``value`` and ``slots`` (when given) are integers of at least ``low``, and
    ``value <= slots``."""
    check_int(name, value, low)
    if slots is not None:
        check_int(slots_name, slots, low)
        if value > slots:
            raise ValueError(f"{name} ({value}) must not exceed {slots_name} ({slots})")


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
        _within_slots("num_agents", self.num_agents, "max_agents", self.max_agents, 1)
        if self.min_agents is not None:
            _within_slots("min_agents", self.min_agents, "num_agents", self.num_agents, 1)
        check_choice("action_mode", self.action_mode, ACTION_MODES)
        check_int("decision_period", self.decision_period)
        check_positive("goal_tolerance", self.goal_tolerance)
        check_choice("arrived", self.arrived, ARRIVED_SEMANTICS)
        check_choice("ended", self.ended, WORLD_SEMANTICS)
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
    # m: bodies and walls this far from a pedestrian do not act on it (ORCA: RVO2's
    # neighborDist); None: every body and wall does, as the published laws have it. With a
    # range, crowds from neighbors.GRID_FROM_HUMANS pedestrians find their neighbours through
    # cell lists, and on building floors the walls come from the map's wall grid.
    human_range: float | None = None
    human_search: str = "auto"  # with a range: "auto", "grid" (cell lists) or "all" (dense)
    human_cell_capacity: int = 0  # bodies per cell list (0: 6 per m^2 of cell)
    # the social-force constants: "published", or a preset fitted to recorded people
    # ("eth_ucy": sgjax.humans.calibrated)
    human_constants: str = "published"
    # recorded people ("recorded:FILE" scenarios): "ghost", "pause" or "handover"
    # (sgjax.humans.replay), or "off" (the recording's space with num_humans simulated
    # pedestrians instead); None there means "ghost"
    human_replay: str | None = None

    def __post_init__(self) -> None:
        check_bool("humans_see_robots", self.humans_see_robots)
        if self.human_range is not None:
            check_positive("human_range", self.human_range)
        check_choice("human_search", self.human_search, SEARCHES)
        if not isinstance(self.human_cell_capacity, int) or self.human_cell_capacity < 0:
            raise ValueError(f"human_cell_capacity must be an integer >= 0, got "
                             f"{self.human_cell_capacity!r}")
        if self.human_search == "grid" and self.human_range is None:
            raise ValueError("human_search='grid' needs human_range (m): the cell lists hold "
                             "the bodies within that range")
        _within_slots("num_humans", self.num_humans, "max_humans", self.max_humans, 0)
        check_positive("human_radius", self.human_radius)
        check_choice("human_model", self.human_model, FORCE_MODELS)
        check_choice("human_constants", self.human_constants, CONSTANT_SETS)
        if self.human_constants != "published":
            fitted_constants(self.human_constants, self.human_model)  # the law has a fit
        if self.human_replay is not None:
            check_choice("human_replay", self.human_replay, (*REPLAY_MODES, "off"))
        check_choice("human_walls", self.human_walls, WALL_MODELS)
        check_choice("human_goals", self.human_goals, GOAL_MODES)
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
                           wall_model=self.human_walls, goal_mode=self.human_goals,
                           neighbor_range=self.human_range, neighbor_search=self.human_search,
                           cell_capacity=self.human_cell_capacity,
                           replay=None if self.human_replay == "off" else self.human_replay)


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
        check_positive("dt", self.dt)
        if self.substeps is not None:
            check_int("substeps", self.substeps)
        check_positive("time_limit", self.time_limit)
        check_int("num_arcs", self.num_arcs)
        check_int("contact_passes", self.contact_passes)

    @property
    def max_steps(self) -> int:
        """Steps before truncation: ``ceil(time_limit / dt)``."""
        return math.ceil(self.time_limit / self.dt - 1e-9)


@dataclasses.dataclass(frozen=True)
class WorldOptions:
    """Generated worlds (a scenario ``"generated:<family>"``): the ranges the family's
    parameters are drawn from, on top of its defaults (``{name: [low, high]}`` or ``{name:
    value}``, held as sorted ``(name, low, high)`` rows; checked against the family by
    ``make``), and how many worlds a reset proposes to find a valid one (the first valid of
    K; a reset whose K proposals are all invalid keeps the first and flags it). The default
    families' default ranges give valid worlds only, so one proposal; raise it where narrow
    ranges make invalid worlds likely (a draw costs K worlds)."""

    world_ranges: tuple[tuple[str, float, float], ...] = ()
    world_proposals: int = 1
    # (first, count): play only the worlds with these seeds (a held-out split, docs/generated.md)
    world_seeds: tuple[int, int] | None = None
    # (first, count): never draw a world of this split (training beside a held-out split)
    world_holdout: tuple[int, int] | None = None
    # every world a seed and values, and a reset plays the level the state's next_level holds
    # when one is chosen (a trainer's curriculum of worlds: train/configs, docs/generated.md)
    world_levels: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "world_ranges", _range_rows(self.world_ranges))
        check_int("world_proposals", self.world_proposals)
        if not isinstance(self.world_levels, bool):
            raise ValueError(f"world_levels must be true or false, got {self.world_levels!r}")
        for name in ("world_seeds", "world_holdout"):
            value = getattr(self, name)
            if value is None:
                continue
            if (not isinstance(value, list | tuple) or len(value) != 2
                    or not all(isinstance(v, int) and not isinstance(v, bool) for v in value)
                    or value[0] < 0 or value[1] < 1 or value[0] + value[1] > 2**32):
                raise ValueError(f"{name} must be [first, count] (integers, first >= 0, "
                                 f"count >= 1, below 2**32), got {value!r}")
            object.__setattr__(self, name, (int(value[0]), int(value[1])))

    def ranges(self, family: str | None = None) -> dict[str, tuple[float, float]]:
        """``{name: (low, high)}``; with ``family``, the ranges that family takes: every
        unprefixed row, and the rows named ``"<family>.<parameter>"`` (prefix dropped), so
        that one batch of several families can set a parameter of one of them
        (``{"doorway.ways": [1, 2]}``); rows of other families' prefixes left out."""
        if family is None:
            return {name: (low, high) for name, low, high in self.world_ranges}
        return {parameter: pair for owner, parameter, pair in self._owned_rows()
                if owner in ("", family)}

    def family_prefixes(self) -> dict[str, dict[str, tuple[float, float]]]:
        """``{family: {parameter: (low, high)}}`` of the rows named ``"<family>.<parameter>"``."""
        out: dict[str, dict[str, tuple[float, float]]] = {}
        for owner, parameter, pair in self._owned_rows():
            if owner:
                out.setdefault(owner, {})[parameter] = pair
        return out

    def _owned_rows(self) -> list[tuple[str, str, tuple[float, float]]]:
        """``(family or "", parameter, (low, high))`` of every row."""
        return [(*name.rpartition(".")[::2], (low, high)) for name, low, high in self.world_ranges]


def _range_rows(value: Any) -> tuple[tuple[str, float, float], ...]:
    """``world_ranges`` as sorted ``(name, low, high)`` rows, from a mapping of ranges or
    numbers or from rows; a ValueError names a malformed entry."""
    if isinstance(value, Mapping):
        items = list(value.items())
    else:
        try:
            items = [(row[0], tuple(row[1:])) for row in value]
        except (TypeError, IndexError, KeyError):  # a row that is no sequence ({} or a number)
            raise ValueError(f"world_ranges must be a mapping of parameter names to [low, high]"
                             f", got {value!r}") from None
    rows = []
    for name, pair in items:
        if isinstance(pair, int | float) and not isinstance(pair, bool):
            pair = (pair, pair)
        if (not isinstance(name, str) or not isinstance(pair, tuple | list) or len(pair) != 2
                or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in pair)):
            raise ValueError(f"world_ranges: {name!r}: expected [low, high] (or one number), "
                             f"got {pair!r}")
        rows.append((name, float(pair[0]), float(pair[1])))
    return tuple(sorted(rows))


GROUPS: dict[str, type] = {"robots": RobotOptions, "humans": HumanOptions,
                           "terms": TermOptions, "physics": PhysicsOptions,
                           "worlds": WorldOptions}
# Flat keyword -> its group.
KEYWORDS: dict[str, str] = {f.name: group for group, cls in GROUPS.items()
                            for f in dataclasses.fields(cls)}


@dataclasses.dataclass(frozen=True)
class MakeOptions:
    """Every option of :func:`sgjax.make`, in five groups."""

    robots: RobotOptions = dataclasses.field(default_factory=RobotOptions)
    humans: HumanOptions = dataclasses.field(default_factory=HumanOptions)
    terms: TermOptions = dataclasses.field(default_factory=TermOptions)
    physics: PhysicsOptions = dataclasses.field(default_factory=PhysicsOptions)
    worlds: WorldOptions = dataclasses.field(default_factory=WorldOptions)

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

    def to_dict(self) -> dict[str, dict[str, Any]]:
        """Every option by group as plain data (tuples as lists), the form a checkpoint
        stores: ``{"robots": {"num_agents": 4, ...}, "humans": {...}, "terms": {...},
        "physics": {...}, "worlds": {...}}``; :meth:`from_dict` reads it back (a checkpoint
        written before a group existed has its defaults)."""
        return {group: {f.name: thaw(getattr(getattr(self, group), f.name))
                        for f in dataclasses.fields(cls)} for group, cls in GROUPS.items()}

    @classmethod
    def from_dict(cls, data: Any, where: str = "options") -> MakeOptions:
        """Options from the nested form of :meth:`to_dict` (a group or an option left out
        keeps its default). An unknown group or option is a ``ValueError`` naming ``where``
        and the nearest valid name."""
        if not isinstance(data, Mapping):
            raise ValueError(f"{where} must be a mapping of {', '.join(GROUPS)}, got {data!r}")
        check_keys(where, data, list(GROUPS), "group")
        keywords: dict[str, Any] = {}
        for group, values in data.items():
            if not isinstance(values, Mapping):
                raise ValueError(f"{where}.{group} must be a mapping of its options, got "
                                 f"{values!r}")
            check_keys(f"{where}.{group}", values, group_keywords(group), "option")
            keywords.update(values)
        return cls.from_keywords(where, **keywords)


def group_keywords(group: str) -> list[str]:
    """The flat keywords of one group (``"robots"``, ``"humans"``, ``"terms"``,
    ``"physics"``, ``"worlds"``)."""
    return [f.name for f in dataclasses.fields(GROUPS[group])]


def check_keywords(where: str, keywords: Any) -> None:
    """Raise ``TypeError`` naming the nearest valid keyword for any unknown one."""
    check_keys(where, keywords, list(KEYWORDS), "option", TypeError)
