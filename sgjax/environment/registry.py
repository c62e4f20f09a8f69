"""``sgjax.make``: build an environment and its default params from a scenario id."""

from __future__ import annotations

import dataclasses
import functools
import math
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from sgjax.dynamics.limits import RobotPreset, resolve_robots, robot_params
from sgjax.dynamics.planner import PlannerConfig, PlannerParams
from sgjax.environment.env import EnvConfig, SocialNavEnv
from sgjax.environment.options import MakeOptions
from sgjax.environment.presets import resolve_terms
from sgjax.environment.worlds import WorldDraw, WorldSource, source_for
from sgjax.humans.hsfm import MAX_SUBSTEP as HSFM_MAX_SUBSTEP
from sgjax.humans.map_params import human_params
from sgjax.humans.pedestrians import HumanConfig, HumanParams, spawn_humans
from sgjax.humans.recorded_scene import PREFIX as RECORDED
from sgjax.humans.recorded_scene import read_scene, scene_recording
from sgjax.maps.arrays import MapArrays, compile_map, spawn_groups
from sgjax.maps.crowd_scenarios import CROWD_SCENARIOS
from sgjax.maps.generated.export import world_map
from sgjax.maps.generated.families import PREFIX as GENERATED
from sgjax.maps.generated.families import family
from sgjax.maps.io import load, shipped_map_names
from sgjax.maps.sampling import sample_starts_goals
from sgjax.maps.schema import MapSpec, parse_map
from sgjax.types import EnvParams
from sgjax.validation import suggest

CAPACITY_TRIALS = 64
_HUMAN_DEFAULTS = {f.name: f.default for f in dataclasses.fields(HumanParams)}
# m/s: the fastest pedestrian at the default params (top desired speed x the speed cap)
HUMAN_TOP_SPEED = _HUMAN_DEFAULTS["speed_max"] * _HUMAN_DEFAULTS["max_speed_factor"]
CROWD_SOURCE = "sgjax.maps.crowd_scenarios."  # a crowd scenario's MapSpec.source prefix
PLANNER_SLACK = 0.2  # m: how much obstacle_margin may grow after make() with walls still seen


def registered() -> list[str]:
    """Scenario ids accepted by :func:`make`: the shipped map names, then the generated crowd
    scenarios (``sgjax.maps.crowd_scenarios``)."""
    return shipped_map_names() + list(CROWD_SCENARIOS)


def make(scenario: str | Path | MapSpec, options: MakeOptions | None = None,
         **keywords: Any) -> tuple[SocialNavEnv, EnvParams]:
    """Build the environment for ``scenario``: a shipped id, a path to a map JSON file, a
    ``MapSpec`` (for example from ``sgjax.maps.import_socialgym``), ``generated:FAMILY`` or
    ``recorded:TRACK_FILE``. Returns ``(env, params)``.

    Options (``sgjax.environment.options``: defaults, units and groups) come as flat keywords,
    on top of ``options`` when given: for robots ``num_agents``, ``max_agents``, ``robots``,
    ``action_mode``, ``goal_tolerance``; for pedestrians ``num_humans``, ``max_humans``,
    ``human_model``, ``human_walls``, ``human_goals``, ``human_radius``, ``human_range``,
    ``human_search``, ``human_cell_capacity``, ``human_replay``; for the observation / reward /
    ender terms ``observations``, ``rewards``, ``enders``, ``terms``, ``observation_preset``,
    ``reward_preset`` (``docs/terms.md``); for physics ``dt``, ``substeps``, ``time_limit``,
    ``num_arcs``, ``contact_passes``.
    """
    label = scenario if isinstance(scenario, str | Path) else getattr(scenario, "name", "map")
    if isinstance(scenario, str) and scenario in CROWD_SCENARIOS:
        scenario = CROWD_SCENARIOS[scenario]()
    crowd = isinstance(scenario, MapSpec) and scenario.source.startswith(CROWD_SOURCE)
    if crowd and "human_goals" not in keywords and (
            options is None or options.humans.human_goals == "random"):
        keywords["human_goals"] = "routes"  # pedestrians walk the scenario's routes
    opts = (options or MakeOptions()).replace(where=f"make({str(label)!r})", **keywords)
    scenario, recording, opts = _recorded(scenario, opts, label)
    robot_opts, human_opts, term_opts, physics = opts.robots, opts.humans, opts.terms, opts.physics
    is_spec = isinstance(scenario, MapSpec)
    generated = isinstance(scenario, str) and scenario.startswith(GENERATED)
    is_path = not is_spec and not generated and (
        str(scenario).endswith(".json") or Path(str(scenario)).exists())
    if not is_spec and not is_path and not generated and scenario not in registered():
        raise KeyError(f"unknown scenario {scenario!r}{suggest(str(scenario), registered())}; "
                       f"registered scenarios are: {', '.join(registered())} (or pass a path "
                       "to a map .json file)")

    max_agents = robot_opts.slots
    presets: list[RobotPreset] = [p for _, p in resolve_robots(robot_opts.robots, max_agents)]
    human_config = human_opts.config()
    observer, rewarder, reward_params, enders = resolve_terms(
        observations=term_opts.resolved_observations, rewards=term_opts.resolved_rewards,
        enders=term_opts.enders, terms=term_opts.terms,
    )
    substeps = _substeps(physics.substeps, presets, physics.dt,
                         (HUMAN_TOP_SPEED, human_opts.human_radius) if human_config.max_humans
                         else None,
                         HSFM_MAX_SUBSTEP if human_config.max_humans
                         and human_config.force_model == "hsfm" else None)

    largest = max(p.radius for p in presets)
    planner_config = PlannerConfig(num_arcs=physics.num_arcs)
    planner_params = PlannerParams()
    planner_reach, reach = _grid_reaches(planner_config, planner_params, largest, human_config)
    world, spec, map_arrays, template = _scenario_map(scenario, generated, is_spec, opts,
                                                      largest, reach, planner_reach)
    action_dim = 3 if any(p.model == "omnidirectional" for p in presets) else 2
    config = EnvConfig(
        scenario=spec.name, max_agents=max_agents, action_mode=robot_opts.action_mode,
        action_dim=action_dim, substeps=substeps, planner=planner_config,
        contact_passes=physics.contact_passes, humans=human_config, observer=observer,
        rewarder=rewarder, enders=enders,
        num_zones=len(spec.zones) if world is None else world.capacity.zones,
        arrived=robot_opts.arrived, ended=robot_opts.ended,
        decision_period=robot_opts.decision_period, world=world,
    )
    params = EnvParams(
        robots=robot_params(presets), map=map_arrays, planner=planner_params, reward=reward_params,
        humans=human_params(spec, human_config, human_opts.num_humans, human_opts.human_radius,
                            human_opts.humans_see_robots, human_opts.human_groups,
                            human_opts.human_constants),
        num_agents=jnp.asarray(robot_opts.num_agents, jnp.int32),
        dt=jnp.asarray(physics.dt, jnp.float32),
        max_steps=jnp.asarray(physics.max_steps, jnp.int32),
        goal_tolerance=jnp.asarray(robot_opts.goal_tolerance, jnp.float32),
        min_agents=jnp.asarray(robot_opts.min_agents or 0, jnp.int32),
    )
    if template is not None:  # a generated family: the template world's pedestrian slots too
        params = template.params_of(params)
    if recording is not None:
        params = params.replace(humans=params.humans.replace(recording=recording))
    _check_capacity(spec.source, params, max_agents, human_config)
    return SocialNavEnv(config, params), params


def _recorded(name: Any, opts: MakeOptions, label: Any) -> tuple[Any, Any, MakeOptions]:
    """A ``recorded:FILE`` scenario: its map, its recording (windows of the episode's
    length) and the options with one pedestrian slot per person of the fullest window
    (``num_humans`` and ``max_humans`` are the recording's to set). Any other scenario:
    ``(name, None, opts)``, refusing ``human_replay``."""
    humans = opts.humans
    if not (isinstance(name, str) and name.startswith(RECORDED)):
        if humans.human_replay is not None:
            raise ValueError(f"make({str(label)!r}): human_replay={humans.human_replay!r} "
                             f"replays a recording: give a '{RECORDED}FILE' scenario")
        return name, None, opts
    tracks, spec = read_scene(name[len(RECORDED):])
    if humans.human_replay == "off":  # the recording's space, simulated pedestrians
        return spec, None, opts
    if humans.num_humans or humans.max_humans is not None:
        raise ValueError(f"make({name!r}): num_humans and max_humans come from the recording "
                         "(one slot per person of its fullest window); leave them out, or "
                         "give human_replay='off' for simulated pedestrians in its space")
    recording = scene_recording(tracks, opts.physics.time_limit)
    people = int(recording.x.shape[2])
    opts = opts.replace(where=f"make({name!r})", num_humans=people, max_humans=people,
                        human_replay=humans.human_replay or "ghost")
    return spec, recording, opts


def _grid_reaches(planner_config: PlannerConfig, planner_params: PlannerParams, largest: float,
                  human_config: HumanConfig) -> tuple[float, float]:
    """``(planner, grid)`` m: how far the local planner looks for walls (its longest arc for
    the largest robot, ``largest`` m radius, with the obstacle margin and slack), and how far
    the map's wall grid lists walls around each cell: the planner's reach, or the pedestrians'
    range where it is longer (their wall terms read the grid too:
    :mod:`sgjax.humans.near_walls`)."""
    planner = (max(planner_config.arc_lengths) + largest + planner_params.obstacle_margin
               + PLANNER_SLACK)
    if human_config.max_humans and human_config.neighbor_range is not None:
        return planner, max(planner, human_config.neighbor_range)
    return planner, planner


def floor_diagonal(spec: MapSpec) -> float:
    """The diagonal (m) of the box holding ``spec``'s walls, nodes and bounds: no two points of
    the floor are farther apart."""
    points = np.concatenate([spec.walls[:, :2], spec.walls[:, 2:], spec.node_positions,
                             np.reshape(spec.bounds, (2, 2))], axis=0)
    return float(np.hypot(*(points.max(axis=0) - points.min(axis=0))))


def _scenario_map(scenario: Any, generated: bool, is_spec: bool, opts: MakeOptions,
                  largest: float, reach: float, planner_reach: float
                  ) -> tuple[WorldSource | None, MapSpec, MapArrays, WorldDraw | None]:
    """The scenario's map for robots up to ``largest`` m with wall lists reaching ``reach``
    m (:func:`_grid_reaches`): ``(world source or None, spec, arrays, template draw or None)``;
    a map spec or file is validated again for the robots that will drive it. A pedestrian
    range at least the floor's diagonal puts every wall in range everywhere: the lists would
    hold every wall in every cell of a grid grown by the range on each side (a 100 m range
    over a 50 m floor: a minute to build), so they keep the planner's reach and pedestrians
    read every wall with the range applied (:func:`sgjax.humans.near_walls.uses_wall_lists`:
    the same forces)."""
    if generated:
        source, spec, template = _generated(scenario, opts, largest, reach)
        return source, spec, template.map, template
    if is_spec:
        spec = parse_map(scenario.to_json(), source=scenario.source, clearance=largest)
    else:
        spec = load(scenario, clearance=largest)
    if reach > planner_reach and reach >= floor_diagonal(spec):
        reach = planner_reach
    return None, spec, compile_map(spec, reach=reach), None


def _generated(name: str, opts: MakeOptions, largest: float, reach: float
               ) -> tuple[WorldSource, MapSpec, WorldDraw]:
    """A generated world family as an environment's world source, with its template world (key
    0: the default params' map and pedestrian slots, which fix every shape) as a map spec and
    its draw."""
    fam = family(name)
    humans = opts.humans
    if humans.slots:  # pedestrians: slots per world; no sampled wall points, no map routes
        for option, value, refused in (("human_walls", humans.human_walls, "points"),
                                       ("human_goals", humans.human_goals, "routes")):
            if value == refused:
                raise ValueError(f"make({name!r}): {option}={refused!r} needs a fixed map; "
                                 f"generated worlds take the other {option} values")
    w = opts.worlds
    if w.world_levels and w.world_seeds is not None:
        raise ValueError(f"make({name!r}): world_levels (a trainer picks each world) and "
                         "world_seeds (play a split's worlds) exclude each other")
    for owner, rows in w.family_prefixes().items():  # "<family>.<parameter>" rows: real names
        family(owner).ranges(rows)
    source = source_for(fam.name, w.ranges(fam.name), float(largest), w.world_proposals,
                        float(reach),
                        check_dilemma=False, seeds=w.world_seeds, holdout=w.world_holdout,
                        levels=w.world_levels,
                        human_radius=humans.human_radius if humans.slots else 0.0)
    template, draw = _template(source)
    if not bool(draw.valid):
        raise ValueError(f"make({name!r}): the world of key 0 fails the family's checks for "
                         f"robots of radius {largest} m (passages too narrow for them?); "
                         f"narrow the ranges (world_ranges)")
    data = world_map(template, f"{GENERATED}{fam.name}", fam.description, draw.values)
    spec = parse_map(data, source=f"{GENERATED}{fam.name}", clearance=largest)
    return source, spec, draw


@functools.lru_cache(maxsize=64)
def _template(source: WorldSource) -> tuple[Any, WorldDraw]:
    """The world of key 0 (the first valid proposal, as a reset draws it) and its draw; kept
    per source (a frozen dataclass: every setting a draw depends on), so that making the same
    family again in a process (a judge's arms, a notebook) does not trace and compile its
    generator again."""
    return jax.jit(source.chosen)(jax.random.key(0))


def _substeps(
    value: Any, presets: list[RobotPreset], dt: float, human: tuple[float, float] | None,
    longest: float | None = None,
) -> int:
    """Sub-steps such that two robots closing head-on at full speed never cross centres, nor a
    robot and a pedestrian (``human = (top speed m/s, radius m)``) when there are any, and,
    when ``longest`` (s) is given (the HSFM pedestrians' stiff contact terms), no sub-step is
    longer than it."""
    fastest = max(max(p.max_speed, p.max_reverse_speed) for p in presets)
    smallest = min(p.radius for p in presets)
    needed = max(1, math.floor(fastest * dt / smallest) + 1)
    if human is not None:
        closing, reach = fastest + human[0], smallest + human[1]
        needed = max(needed, math.floor(closing * dt / reach) + 1)
    if longest is not None:
        needed = max(needed, math.ceil(dt / longest - 1e-9))
    if value is None:
        return needed
    substeps = int(value)
    if substeps < needed:
        raise ValueError(
            f"substeps={substeps} is too few for dt={dt} s: robots at {fastest} m/s with radius "
            f"{smallest} m could pass through each other or a pedestrian"
            + (f", or HSFM pedestrians' sub-steps exceed {longest} s" if longest else "")
            + f"; use substeps >= {needed}"
        )
    return substeps


def _content_key(*trees: Any) -> tuple:
    """A hashable key for the values of some pytrees of arrays (shapes, dtypes and bytes)."""
    leaves = [np.asarray(leaf) for tree in trees for leaf in jax.tree.leaves(tree)]
    return tuple((leaf.shape, leaf.dtype.str, leaf.tobytes()) for leaf in leaves)


@functools.partial(jax.jit, static_argnames=("max_agents", "human_config"))
def _placements(keys: Array, m: MapArrays, robot_radius: Array, hp: HumanParams,
                max_agents: int, human_config: HumanConfig) -> tuple[Array, Array]:
    """For each key of ``keys [T]``: how many robots were placed (all ``max_agents`` wanted) and
    how many pedestrians found a spawn slot beside them (``hp.num_humans`` wanted), as ``reset``
    places them (without routes or observations). Returns two ``[T]`` int counts."""

    def one(key: Array) -> tuple[Array, Array]:
        key_robots, key_humans = jax.random.split(key)
        start, _, placed = sample_starts_goals(key_robots, m, robot_radius,
                                               jnp.ones(max_agents, bool))
        if not human_config.max_humans:
            return jnp.sum(placed), jnp.zeros((), jnp.int32)
        humans = spawn_humans(key_humans, human_config, hp, m, m.node_x[start], m.node_y[start],
                              robot_radius, placed)
        return jnp.sum(placed), jnp.sum(humans.active)

    return jax.vmap(one)(keys)


# (map, radii and counts by value, max_agents, HumanConfig) -> fewest robots, pedestrians placed:
# a second ``make`` of the same world checks nothing again.
_FEWEST_PLACED: dict[tuple, tuple[int, int]] = {}


def _check_capacity(source: str, params: EnvParams, max_agents: int,
                    human_config: HumanConfig) -> None:
    """Fail early if the map cannot place ``max_agents`` robots with distinct starts and goals,
    or ``max_humans`` pedestrians on free spawn slots beside them."""
    wanted = 0 if human_config.replay else human_config.max_humans  # replayed: no slots
    valid = params.humans.spawn_valid  # a generated world's lattice is masked
    slots = int(params.humans.spawn_x.shape[0] if valid is None else jnp.sum(valid))
    radius = float(params.humans.radius)
    if slots < wanted:
        raise ValueError(
            f"{source}: cannot place max_humans={wanted} pedestrians of radius "
            f"{radius} m: the map has only {slots} spawn slots"
        )
    hp = params.humans.replace(num_humans=jnp.asarray(wanted, jnp.int32))
    trees = (params.map, params.robots.radius, hp)
    key = (_content_key(*trees), max_agents, human_config)
    if key not in _FEWEST_PLACED:
        counts = _placements(jax.random.split(jax.random.key(0), CAPACITY_TRIALS), *trees,
                             max_agents=max_agents, human_config=human_config)
        _FEWEST_PLACED[key] = tuple(int(jnp.min(c)) for c in counts)
    robots, humans = _FEWEST_PLACED[key]
    if robots < max_agents:
        raise ValueError(
            f"{source}: cannot place max_agents={max_agents} robots with distinct starts and goals "
            f"and non-overlapping bodies (managed only {robots} in some of {CAPACITY_TRIALS} "
            "draws); use fewer robots or smaller ones"
        )
    if humans < wanted:
        raise ValueError(
            f"{source}: cannot place max_humans={wanted} pedestrians of radius "
            f"{radius} m beside {max_agents} robots (the map has {slots} spawn slots; managed "
            f"only {humans} in some draws); use fewer pedestrians"
        )


def robots_that_fit(scenario: str | Path | MapSpec, robots: str = "socialgym",
                    trials: int = CAPACITY_TRIALS) -> int:
    """How many ``robots`` (a preset name, ``docs/robots.md``) ``reset`` places on the map in
    every one of ``trials`` draws: distinct starts and goals, bodies apart (the check ``make``
    runs for ``max_agents``)."""
    spec = scenario if isinstance(scenario, MapSpec) else load(scenario)
    env, params = make(spec, num_agents=1, max_agents=1, robots=robots)
    starts = {s for group, _ in spawn_groups(spec) for s in group}
    most = max(1, len(starts))
    radius = jnp.full(most, params.robots.radius[0])
    hp = params.humans.replace(num_humans=jnp.asarray(0, jnp.int32))
    placed, _ = _placements(jax.random.split(jax.random.key(0), trials), params.map, radius, hp,
                            max_agents=most, human_config=HumanConfig(max_humans=0))
    return int(jnp.min(placed))
