"""``sgjax.make``: build an environment and its default params from a scenario id."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from sgjax.dynamics.limits import RobotPreset, resolve_robots, robot_params
from sgjax.env import ACTION_MODES, EnvConfig, EnvParams, RewardWeights, SocialNavEnv
from sgjax.maps.arrays import compile_map
from sgjax.maps.io import load, shipped_map_names
from sgjax.maps.sampling import sample_starts_goals
from sgjax.maps.schema import MapSpec, parse_map
from sgjax.planner import PlannerConfig, PlannerParams

DEFAULTS: dict[str, Any] = {
    "num_agents": 4,  # robots in an episode (a param: change it without recompiling)
    "max_agents": None,  # static maximum; default: num_agents
    "action_mode": "go_stop",  # or "continuous"
    "robots": "socialgym",  # preset name, RobotPreset, or a list (one per slot, cycled)
    "dt": 0.1,  # s per step
    "substeps": None,  # integration sub-steps per step; default: the fewest that are safe
    "time_limit": 75.0,  # s before truncation (SocialGym: 3000 steps x 0.025 s)
    "goal_tolerance": 0.5,  # m (SocialGym's success radius)
    "num_arcs": 11,  # local planner arcs (SocialGym sampled 41; see bench/ for the cost)
    "contact_passes": 1,  # robot-robot separation passes per sub-step (more: less overlap)
}
CAPACITY_TRIALS = 64
PLANNER_SLACK = 0.2  # m: how much obstacle_margin may grow after make() with walls still seen


def registered() -> list[str]:
    """Scenario ids accepted by :func:`make` (the shipped map names)."""
    return shipped_map_names()


def make(scenario: str | Path | MapSpec, **overrides: Any) -> tuple[SocialNavEnv, EnvParams]:
    """Build the environment for ``scenario``: a shipped id, a path to a map JSON file, or a
    ``MapSpec`` (for example from ``sgjax.maps.import_socialgym``).

    Overrides (see ``sgjax.registry.DEFAULTS``): ``num_agents``, ``max_agents``,
    ``action_mode``, ``robots``, ``dt``, ``substeps``, ``time_limit``, ``goal_tolerance``,
    ``num_arcs``, ``contact_passes``. Returns ``(env, params)``.
    """
    unknown = sorted(set(overrides) - set(DEFAULTS))
    if unknown:
        raise TypeError(f"make({scenario!r}): unknown override(s) {unknown}; "
                        f"valid overrides are: {', '.join(DEFAULTS)}")
    opts = {**DEFAULTS, **overrides}
    is_spec = isinstance(scenario, MapSpec)
    is_path = not is_spec and (str(scenario).endswith(".json") or Path(str(scenario)).exists())
    if not is_spec and not is_path and scenario not in registered():
        raise KeyError(f"unknown scenario {scenario!r}; registered scenarios are: "
                       f"{', '.join(registered())} (or pass a path to a map .json file)")

    num_agents = _positive_int("num_agents", opts["num_agents"])
    max_agents = num_agents if opts["max_agents"] is None else _positive_int(
        "max_agents", opts["max_agents"])
    if num_agents > max_agents:
        raise ValueError(f"num_agents ({num_agents}) must not exceed max_agents ({max_agents})")
    if opts["action_mode"] not in ACTION_MODES:
        raise ValueError(f"action_mode must be one of {ACTION_MODES}, got {opts['action_mode']!r}")
    dt = _positive_float("dt", opts["dt"])
    time_limit = _positive_float("time_limit", opts["time_limit"])
    goal_tolerance = _positive_float("goal_tolerance", opts["goal_tolerance"])
    slots = resolve_robots(opts["robots"], max_agents)
    presets: list[RobotPreset] = [p for _, p in slots]
    substeps = _substeps(opts["substeps"], presets, dt)

    largest = max(p.radius for p in presets)
    if is_spec:  # re-validate against the robots that will drive it
        spec = parse_map(scenario.to_json(), source=scenario.source, clearance=largest)
    else:
        spec = load(scenario, clearance=largest)
    planner_config = PlannerConfig(num_arcs=_positive_int("num_arcs", opts["num_arcs"]))
    planner_params = PlannerParams()
    reach = (max(planner_config.arc_lengths) + largest + planner_params.obstacle_margin
             + PLANNER_SLACK)
    map_arrays = compile_map(spec, reach=reach)
    action_dim = 3 if any(p.model == "omnidirectional" for p in presets) else 2
    config = EnvConfig(
        scenario=spec.name, max_agents=max_agents, action_mode=opts["action_mode"],
        action_dim=action_dim, substeps=substeps, planner=planner_config,
        contact_passes=_positive_int("contact_passes", opts["contact_passes"]),
    )
    params = EnvParams(
        robots=robot_params(presets),
        map=map_arrays,
        planner=planner_params,
        reward=RewardWeights(),
        num_agents=jnp.asarray(num_agents, jnp.int32),
        dt=jnp.asarray(dt, jnp.float32),
        max_steps=jnp.asarray(math.ceil(time_limit / dt - 1e-9), jnp.int32),
        goal_tolerance=jnp.asarray(goal_tolerance, jnp.float32),
    )
    _check_capacity(spec.source, params, max_agents)
    return SocialNavEnv(config, params), params


def _positive_int(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def _positive_float(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not (
        math.isfinite(value) and value > 0
    ):
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    return float(value)


def _substeps(value: Any, presets: list[RobotPreset], dt: float) -> int:
    """Sub-steps such that two robots closing head-on at full speed never cross centres."""
    fastest = max(max(p.max_speed, p.max_reverse_speed) for p in presets)
    smallest = min(p.radius for p in presets)
    needed = max(1, math.floor(fastest * dt / smallest) + 1)
    if value is None:
        return needed
    substeps = _positive_int("substeps", value)
    if substeps < needed:
        raise ValueError(
            f"substeps={substeps} is too few for dt={dt} s: robots at {fastest} m/s with radius "
            f"{smallest} m could pass through each other; use substeps >= {needed}"
        )
    return substeps


def _check_capacity(source: str, params: EnvParams, max_agents: int) -> None:
    """Fail early if the map cannot place ``max_agents`` robots with distinct starts and goals."""
    wanted = jnp.ones(max_agents, bool)
    keys = jax.random.split(jax.random.key(0), CAPACITY_TRIALS)
    placed = jax.jit(jax.vmap(
        lambda k: sample_starts_goals(k, params.map, params.robots.radius, wanted)[2]
    ))(keys)
    fewest = int(jnp.min(jnp.sum(placed, axis=1)))
    if fewest < max_agents:
        raise ValueError(
            f"{source}: cannot place max_agents={max_agents} robots with distinct starts and goals "
            f"and non-overlapping bodies (managed only {fewest} in some of {CAPACITY_TRIALS} "
            "draws); use fewer robots or smaller ones"
        )
