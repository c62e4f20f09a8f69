"""``sgjax.make``: build an environment and its default params from a scenario id."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from sgjax.dynamics.limits import RobotPreset, resolve_robots, robot_params
from sgjax.env import ACTION_MODES, EnvConfig, EnvParams, SocialNavEnv
from sgjax.humans.crowd import HumanConfig, HumanParams
from sgjax.humans.forces import SocialForceParams
from sgjax.humans.slots import spawn_slots, wall_sample_points
from sgjax.maps.arrays import compile_map
from sgjax.maps.io import load, shipped_map_names
from sgjax.maps.sampling import sample_starts_goals
from sgjax.maps.schema import MapSpec, parse_map
from sgjax.planner import PlannerConfig, PlannerParams
from sgjax.presets import resolve_terms

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
    "num_humans": 0,  # pedestrians in an episode (a param: change it without recompiling)
    "max_humans": None,  # static maximum; default: num_humans
    "human_model": "moussaid",  # social-force law: "moussaid" or "helbing"
    "human_walls": "segments",  # Moussaid wall term: "segments" or "points" (PySocialForce)
    "human_goals": "random",  # at its goal a pedestrian takes a "random" node or will "return"
    "human_radius": 0.25,  # m (SocialGym 0.2, CrowdNav 0.3, PySocialForce 0.35)
    # Terms (docs/terms.md): a preset name, a spec (list / mapping), or a YAML/JSON file.
    "observations": None,  # default: the "default" observation preset
    "rewards": None,  # default: the "default" reward preset (which brings its enders)
    "enders": None,  # default: those of the reward preset
    "terms": None,  # a mapping or file with any of observations / rewards / enders
    "observation_preset": None,  # same as observations=<name>
    "reward_preset": None,  # same as rewards=<name>
}
CAPACITY_TRIALS = 64
HUMAN_TOP_SPEED = 2.6  # m/s: fastest pedestrian (desired speed 2.0 m/s x the 1.3 cap)
# Robots repel pedestrians twice as strongly as a pedestrian does: the Moussaid law ignores body
# sizes, and at weight 1 pedestrians graze a standing robot (tests/test_humans.py). pedsim gets
# the same effect by scaling a robot's distance by robotPosDiffScalingFactor = 1.5.
ROBOT_WEIGHT = 2.0
WALL_RESOLUTION = 10.0  # wall points per metre for human_walls="points" (PySocialForce's)
PLANNER_SLACK = 0.2  # m: how much obstacle_margin may grow after make() with walls still seen


def registered() -> list[str]:
    """Scenario ids accepted by :func:`make` (the shipped map names)."""
    return shipped_map_names()


def make(scenario: str | Path | MapSpec, **overrides: Any) -> tuple[SocialNavEnv, EnvParams]:
    """Build the environment for ``scenario``: a shipped id, a path to a map JSON file, or a
    ``MapSpec`` (for example from ``sgjax.maps.import_socialgym``).

    Overrides (see ``sgjax.registry.DEFAULTS``): ``num_agents``, ``max_agents``,
    ``action_mode``, ``robots``, ``dt``, ``substeps``, ``time_limit``, ``goal_tolerance``,
    ``num_arcs``, ``contact_passes``, for pedestrians ``num_humans``, ``max_humans``,
    ``human_model``, ``human_walls``, ``human_goals``, ``human_radius``, and for the
    observation / reward / ender terms ``observations``, ``rewards``, ``enders``, ``terms``,
    ``observation_preset``, ``reward_preset`` (``docs/terms.md``). Returns ``(env, params)``.
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
    num_humans = _count("num_humans", opts["num_humans"])
    max_humans = num_humans if opts["max_humans"] is None else _count(
        "max_humans", opts["max_humans"])
    if num_humans > max_humans:
        raise ValueError(f"num_humans ({num_humans}) must not exceed max_humans ({max_humans})")
    human_config = HumanConfig(max_humans=max_humans, force_model=opts["human_model"],
                               wall_model=opts["human_walls"], goal_mode=opts["human_goals"])
    human_radius = _positive_float("human_radius", opts["human_radius"])
    observer, rewarder, reward_params, enders = resolve_terms(
        observations=_alias(opts, "observations", "observation_preset"),
        rewards=_alias(opts, "rewards", "reward_preset"),
        enders=opts["enders"], terms=opts["terms"],
    )
    substeps = _substeps(opts["substeps"], presets, dt,
                         (HUMAN_TOP_SPEED, human_radius) if max_humans else None)

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
        humans=human_config, observer=observer, rewarder=rewarder, enders=enders,
        num_zones=len(spec.zones),
    )
    params = EnvParams(
        robots=robot_params(presets),
        map=map_arrays,
        planner=planner_params,
        reward=reward_params,
        humans=human_params(spec, human_config, num_humans, human_radius),
        num_agents=jnp.asarray(num_agents, jnp.int32),
        dt=jnp.asarray(dt, jnp.float32),
        max_steps=jnp.asarray(math.ceil(time_limit / dt - 1e-9), jnp.int32),
        goal_tolerance=jnp.asarray(goal_tolerance, jnp.float32),
    )
    _check_capacity(spec.source, params, max_agents)
    env = SocialNavEnv(config, params)
    if max_humans:
        _check_human_capacity(spec.source, env, params)
    return env, params


def human_params(
    spec: MapSpec, config: HumanConfig, num_humans: int, radius: float
) -> HumanParams:
    """Default pedestrian params for a map: spawn slots for ``radius`` (m), desired speeds
    N(1.34, 0.26) m/s clipped to [0.5, 2.0], a 1.3x speed cap (``socialnav.md`` B1)."""
    slots, slot_nodes = spawn_slots(spec, radius) if config.max_humans else (
        np.zeros((0, 2)), np.zeros((0, 2), np.int64))
    points = (wall_sample_points(spec.walls, WALL_RESOLUTION) if config.wall_model == "points"
              else np.zeros((0, 2)))
    f32 = jnp.float32
    return HumanParams(
        num_humans=jnp.asarray(num_humans, jnp.int32),
        radius=jnp.asarray(radius, f32),
        speed_mean=jnp.asarray(1.34, f32),
        speed_std=jnp.asarray(0.26, f32),
        speed_min=jnp.asarray(0.5, f32),
        speed_max=jnp.asarray(HUMAN_TOP_SPEED / 1.3, f32),
        max_speed_factor=jnp.asarray(1.3, f32),
        waypoint_radius=jnp.asarray(0.75, f32),
        robot_weight=jnp.asarray(ROBOT_WEIGHT, f32),
        forces=SocialForceParams(),
        spawn_x=jnp.asarray(slots[:, 0], f32),
        spawn_y=jnp.asarray(slots[:, 1], f32),
        spawn_nodes=jnp.asarray(slot_nodes, jnp.int32),
        wall_points_x=jnp.asarray(points[:, 0], f32),
        wall_points_y=jnp.asarray(points[:, 1], f32),
    )


def _alias(opts: dict[str, Any], name: str, preset_name: str) -> Any:
    """``opts[name]``, or the preset named by ``opts[preset_name]`` (not both)."""
    value, preset = opts[name], opts[preset_name]
    if preset is None:
        return value
    if value is not None:
        raise ValueError(f"give {name}= or {preset_name}=, not both")
    if not isinstance(preset, str):
        raise ValueError(f"{preset_name} must be a preset name, got {preset!r}")
    return preset


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


def _count(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
        raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
    return int(value)


def _substeps(
    value: Any, presets: list[RobotPreset], dt: float, human: tuple[float, float] | None
) -> int:
    """Sub-steps such that two robots closing head-on at full speed never cross centres, nor a
    robot and a pedestrian (``human = (top speed m/s, radius m)``) when there are any."""
    fastest = max(max(p.max_speed, p.max_reverse_speed) for p in presets)
    smallest = min(p.radius for p in presets)
    needed = max(1, math.floor(fastest * dt / smallest) + 1)
    if human is not None:
        closing, reach = fastest + human[0], smallest + human[1]
        needed = max(needed, math.floor(closing * dt / reach) + 1)
    if value is None:
        return needed
    substeps = _positive_int("substeps", value)
    if substeps < needed:
        raise ValueError(
            f"substeps={substeps} is too few for dt={dt} s: robots at {fastest} m/s with radius "
            f"{smallest} m could pass through each other or a pedestrian; use substeps >= "
            f"{needed}"
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


def _check_human_capacity(source: str, env: SocialNavEnv, params: EnvParams) -> None:
    """Fail early if ``max_humans`` pedestrians do not always find free spawn slots."""
    wanted = env.config.humans.max_humans
    slots = int(params.humans.spawn_x.shape[0])
    if slots < wanted:
        raise ValueError(
            f"{source}: cannot place max_humans={wanted} pedestrians of radius "
            f"{float(params.humans.radius)} m: the map has only {slots} spawn slots"
        )
    full = params.replace(
        num_agents=jnp.asarray(env.max_agents, jnp.int32),
        humans=params.humans.replace(
            num_humans=jnp.asarray(env.config.humans.max_humans, jnp.int32)),
    )
    keys = jax.random.split(jax.random.key(0), CAPACITY_TRIALS // 4)
    states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, full)[1]
    fewest = int(jnp.min(jnp.sum(states.humans.active, axis=1)))
    if fewest < wanted:
        raise ValueError(
            f"{source}: cannot place max_humans={wanted} pedestrians of radius "
            f"{float(params.humans.radius)} m beside {env.max_agents} robots (the map has "
            f"{slots} spawn slots; managed only {fewest} in some draws); use fewer pedestrians"
        )
