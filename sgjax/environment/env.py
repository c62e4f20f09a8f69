"""The multi-robot social-navigation environment: state, params, reset and step.

One environment is written for one episode; batch it with ``jax.vmap`` from outside::

    env, params = sgjax.make("doorway", num_agents=4)
    keys = jax.random.split(jax.random.key(0), 1024)
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))

Robots are ``[R]`` arrays padded to ``env.max_agents``; ``params.num_agents`` of them take part in
an episode (``present``). A robot that reaches its goal is terminated and absorbing (it reads no
actions; reward 0). With ``arrived="settle"`` (the default, as SocialGym 2.0 ran: its arrived
robots kept their GO) its local planner drives it on from where it arrived to its goal point
(within ``SETTLE_TOLERANCE``, or for at most ``SETTLE_SECONDS``), a moving body that reads no
actions and earns nothing, and it parks there, a static body that the others plan around,
collide with and observe; with ``arrived="park"`` it parks at rest where it arrived (up to
``goal_tolerance`` short of its goal); with ``arrived="leave"`` it leaves the world. ``ended``
makes the park-or-leave choice for robots an ender terminates (default ``"leave"``).

Actions (static ``action_mode``):
  * ``"go_stop"``: ``[R]`` ints, 0 = GO (follow the local planner), 1 = STOP (brake at the
    robot's deceleration limit); any other value is an error outside ``jit`` and STOP, flagged
    in ``info["invalid_action"]``, inside it (as is a NaN or infinite continuous action, which
    becomes a zero command);
  * ``"continuous"``: ``[R, d]`` floats in [-1, 1], ``d = 2`` ``(forward, turn)`` or ``d = 3``
    ``(forward, lateral, turn)`` when the team has an omnidirectional robot
    (see :func:`sgjax.dynamics.decode_continuous`).

With ``decision_period=k`` (default 1) robots read new actions only at the steps whose episode
time is a multiple of ``k`` and hold their last one in between (``state.held_action``;
``info["decided"]`` says whether a step read them): a STOP lasts ``k`` steps, a GO too.

Observations, rewards and episode ends are made of named terms (``sgjax.observations``,
``sgjax.rewards``, ``sgjax.terms.enders``; ``docs/terms.md``), chosen in ``make`` by preset or spec.
The default observation is ``[R, 10]``: world pose ``(x, y, cos h, sin h)``, body velocity
``(v_forward, v_lateral, omega)``, goal in the robot frame ``(gx, gy)`` and goal distance; the
default reward is metres gained toward the goal + 100 once on arrival - 10 per collision onset.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from sgjax.dynamics.limits import ACKERMANN
from sgjax.dynamics.models import Kinematics, decode_continuous
from sgjax.dynamics.planner import PlannerConfig, approach, carrot_point, plan, route_progress
from sgjax.environment import physics
from sgjax.environment.physics import Commands
from sgjax.environment.presets import OBSERVATION_PRESETS, REWARD_PRESETS
from sgjax.environment.worlds import Level, WorldDraw, WorldSource
from sgjax.humans.pedestrians import HumanConfig, HumanState, advance_waypoints, spawn_humans
from sgjax.humans.slots import SpawnSlots
from sgjax.kernels.geometry import safe_norm
from sgjax.kernels.row_chunks import chunk_size, update_flagged_rows
from sgjax.kernels.zone_books import start_zones, update_zones
from sgjax.maps.sampling import build_routes, sample_starts_goals
from sgjax.observations import Observer
from sgjax.rewards import Rewarder
from sgjax.terms.contract import TermInput
from sgjax.terms.enders import Enders, Outcome
from sgjax.types import (
    GO,
    STOP,
    CollisionCounts,
    EnvParams,
    EnvState,
    History,
    Layout,
    RobotState,
    episode_params,
)

# Distance (m) from its goal point at which a settling robot parks: SocialGym 2.0's planner
# completes a navigation within 0.1 m of its target (``target_dist_tolerance``).
SETTLE_TOLERANCE = 0.1
# Time (s) after which a settling robot that has not reached its goal point parks where it is:
# its goal is taken by another body, or out of an Ackermann robot's turning circle. From 0.5 m
# out a robot turns and drives onto its goal in well under this.
SETTLE_SECONDS = 5.0

__all__ = ["OBS_SIZE", "EnvConfig", "SocialNavEnv"]

OBS_SIZE = 10  # of the default observation preset


@dataclasses.dataclass(frozen=True)
class EnvConfig:
    """Static settings: they fix shapes or control flow, so changing them recompiles.

    ``make`` builds it from validated options (``sgjax.environment.options``: ``action_mode``,
    ``arrived``, ``ended`` and ``decision_period`` are checked there, once)."""

    scenario: str
    max_agents: int
    action_mode: str = "go_stop"
    action_dim: int = 2
    substeps: int = 1
    contact_passes: int = 1  # robot-robot separation passes per sub-step (see docs/robots.md)
    planner: PlannerConfig = dataclasses.field(default_factory=PlannerConfig)
    humans: HumanConfig = dataclasses.field(default_factory=HumanConfig)
    observer: Observer = dataclasses.field(
        default_factory=lambda: Observer.parse(OBSERVATION_PRESETS["default"]))
    rewarder: Rewarder = dataclasses.field(
        default_factory=lambda: Rewarder.parse(REWARD_PRESETS["default"]["rewards"])[0])
    enders: Enders = dataclasses.field(
        default_factory=lambda: Enders.parse(REWARD_PRESETS["default"]["enders"]))
    num_zones: int = 0  # conflict zones on the map (sizes the zone terms)
    track_zones: bool = False  # keep zone books even when no term reads them (for metrics)
    arrived: str = "settle"  # an arrived robot settles on its goal, parks where it is, or leaves
    ended: str = "leave"  # the same for a robot an ender terminates (e.g. a fatal collision)
    decision_period: int = 1  # steps each action is held (robots read actions every that many)
    # a family of generated worlds: every reset draws a new world into the state (None: the
    # map of params, fixed)
    world: WorldSource | None = None

    @property
    def layout(self) -> Layout:
        """The static sizes that terms and policies read."""
        return Layout(max_agents=self.max_agents, max_humans=self.humans.max_humans,
                      num_zones=self.num_zones, action_mode=self.action_mode,
                      action_dim=self.action_dim)

    @property
    def uses_zones(self) -> bool:
        """Whether the step keeps zone books: a term reads them, or ``track_zones`` asks for
        them (else ``state.zones`` is ``[R, 0]``)."""
        return self.num_zones > 0 and (self.track_zones or any(
            t.uses_zones for t in self.observer.terms + self.rewarder.terms))

    def tracked_zones(self, zone_rect: Array) -> Array:
        """The zone rectangles the step keeps books on: all of them, or none (``[0, 4]``)."""
        return zone_rect if self.uses_zones else zone_rect[:0]


def _set_rows(old: Array, rows: Array, new: Array) -> Array:
    """``old.at[rows[:, 0]].set(new, mode="drop")`` for row numbers ``rows [K, 1]`` in ``[0,
    N]`` (``N = old.shape[0]``: past the end, dropped; ``new [K, ...]``) as one scatter,
    without the index handling that ``.at`` traces again for every leaf of a state."""
    numbers = jax.lax.ScatterDimensionNumbers(
        update_window_dims=tuple(range(1, old.ndim)), inserted_window_dims=(0,),
        scatter_dims_to_operand_dims=(0,))
    return jax.lax.scatter(old, rows, new.astype(old.dtype), numbers,
                           mode=jax.lax.GatherScatterMode.FILL_OR_DROP)


class SocialNavEnv:
    """A scenario's environment. Holds only static configuration; all arrays live in params."""

    def __init__(self, config: EnvConfig, default_params: EnvParams):
        self.config = config
        self._default_params = default_params

    # Environments with equal configs behave the same (all arrays are in params), so they are
    # equal and hash alike: compiled functions taking an environment as a static argument (and
    # the compiled entry points below) are shared between them.
    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and other.config == self.config

    def __hash__(self) -> int:
        return hash(self.config)

    def __repr__(self) -> str:
        c = self.config
        return (f"SocialNavEnv(scenario={c.scenario!r}, max_agents={c.max_agents}, "
                f"action_mode={c.action_mode!r}, substeps={c.substeps})")

    @property
    def max_agents(self) -> int:
        return self.config.max_agents

    @property
    def default_params(self) -> EnvParams:
        return self._default_params

    def action_space(self, params: EnvParams | None = None) -> gymnasium.spaces.Space:
        """One robot's action space."""
        if self.config.action_mode == "go_stop":
            return gymnasium.spaces.Discrete(2)
        return gymnasium.spaces.Box(-1.0, 1.0, (self.config.action_dim,), np.float32)

    def observation_space(self, params: EnvParams | None = None) -> gymnasium.spaces.Box:
        """One robot's observation space: ``Box(D)`` with ``D = env.observation_size``."""
        return gymnasium.spaces.Box(-np.inf, np.inf, (self.observation_size,), np.float32)

    @property
    def observation_size(self) -> int:
        """Length ``D`` of one robot's observation vector."""
        return self.config.observer.size(self.config.layout)

    def observation_slices(self) -> dict[str, slice]:
        """Which slice of the observation vector holds which term."""
        return self.config.observer.slices(self.config.layout)

    def split_observation(self, obs: Array) -> dict[str, Array]:
        """Cut observations ``[..., D]`` into ``{term name: [..., size]}``."""
        return self.config.observer.split(obs, self.config.layout)

    # ------------------------------------------------------------------ reset
    def check_params(self, params: EnvParams) -> None:
        """Raise ``ValueError`` naming the field if concrete params do not fit this environment.

        Called by ``reset``; values traced under ``jit`` cannot be checked there, so check params
        you build on the host before jitting a rollout.
        """
        num_agents = params.num_agents
        if not isinstance(num_agents, jax.core.Tracer):
            n = int(num_agents)
            if not 0 <= n <= self.max_agents:
                raise ValueError(f"params.num_agents must be in [0, max_agents={self.max_agents}]"
                                 f", got {n}")
        fewest = params.min_agents
        if not isinstance(fewest, jax.core.Tracer) and int(fewest) < 0:
            raise ValueError(f"params.min_agents must be >= 0, got {int(fewest)}")
        num_humans = params.humans.num_humans
        if not isinstance(num_humans, jax.core.Tracer):
            n, most = int(num_humans), self.config.humans.max_humans
            if not 0 <= n <= most:
                raise ValueError(f"params.humans.num_humans must be in [0, max_humans={most}], "
                                 f"got {n}")
        radius = params.robots.radius
        if jnp.shape(radius) != (self.max_agents,):
            raise ValueError(f"params.robots.radius: expected shape ({self.max_agents},), "
                             f"got {jnp.shape(radius)}")
        for name in ("dt", "goal_tolerance"):
            value = getattr(params, name)
            if not isinstance(value, jax.core.Tracer) and not float(value) > 0.0:
                raise ValueError(f"params.{name} must be positive, got {float(value)}")
        self.config.rewarder.check_params(params.reward)
        zones = jnp.shape(params.map.zone_rect)
        if zones != (self.config.num_zones, 4):
            raise ValueError(f"params.map.zone_rect: expected shape ({self.config.num_zones}, 4)"
                             f" for this environment, got {zones}")

    def reset(self, key: Array, params: EnvParams) -> tuple[Array, EnvState]:
        """Sample a scenario: starts, goals and routes for ``params.num_agents`` robots (a count
        drawn from ``[params.min_agents, params.num_agents]`` when ``min_agents`` is set).
        Returns ``obs [R, D], state``."""
        self.check_params(params)
        return self._reset_compiled(key, params)

    def params_in(self, state: EnvState, params: EnvParams) -> EnvParams:
        """The params an episode plays under (:func:`sgjax.types.episode_params`)."""
        return episode_params(state, params)

    def reset_in_world(self, key: Array, params: EnvParams, world: WorldDraw
                       ) -> tuple[Array, EnvState]:
        """The episode ``reset`` starts, in the given ``world`` (a draw of this environment's
        family: :meth:`sgjax.environment.worlds.WorldSource.of_seed`) rather than the one its
        key draws: the spawns, goals and robot count from ``key`` as ``reset`` takes them. So
        one world can be played again with another rollout seed (the worst-case
        generalisation report does)."""
        if self.config.world is None:
            raise ValueError(f"reset_in_world: {self.config.scenario!r} is a fixed map, not a "
                             "family of generated worlds")
        self.check_params(params)
        return self._reset(key, params, world=world)

    def _reset(self, key: Array, params: EnvParams, keep: Array | None = None,
               world: WorldDraw | None = None, level: Level | None = None
               ) -> tuple[Array, EnvState]:
        source = self.config.world
        if source is not None:  # a world first, from its own key (or the one given)
            key, key_world = jax.random.split(key)
            if world is None and source.levels:  # the level a trainer chose, or a fresh seed
                world = source.level_draw(
                    key_world, Level.unset(source.family.parameters) if level is None else level)
            elif world is None:
                world = source.draw(key_world)
            params = world.params_of(params)
        key_robots, key_humans = jax.random.split(key)
        fewest = jnp.where(params.min_agents > 0,
                           jnp.minimum(params.min_agents, params.num_agents), params.num_agents)
        count = jax.random.randint(jax.random.fold_in(key, 1), (), fewest, params.num_agents + 1)
        wanted = jnp.arange(self.max_agents) < count
        start, goal, placed = sample_starts_goals(key_robots, params.map, params.robots.radius,
                                                  wanted)
        present = placed if keep is None else placed & jnp.asarray(keep, bool)
        return self._reset_to(start, goal, present, params, key_humans, spawn_present=placed,
                              world=world)

    def reset_subset(self, key: Array, params: EnvParams, keep: Array) -> tuple[Array, EnvState]:
        """The episode ``reset(key, params)`` starts, with only the robots in ``keep [R]`` (bool)
        taking part: the others are removed before the first step, and the pedestrians stand
        where they stand in the full episode (their spawn slots avoid every sampled robot).
        With ``keep`` all True this is ``reset``. The counterfactual metrics play the same
        episode with a robot alone or without it this way (``sgjax.evaluation.counterfactual``)."""
        self.check_params(params)
        return self._reset_subset_compiled(key, params, keep)

    def reset_to(
        self, start: Array, goal: Array, present: Array, params: EnvParams,
        key: Array | None = None,
    ) -> tuple[Array, EnvState]:
        """Start an episode on given routes: node rows ``start, goal [R]`` (int) and which robots
        take part (``present [R]`` bool). Robots start at rest facing their first waypoint.
        ``key`` places the pedestrians (default: ``jax.random.key(0)``)."""
        num_robots = self.max_agents
        for name, value in (("start", start), ("goal", goal), ("present", present)):
            if jnp.shape(value) != (num_robots,):
                raise ValueError(f"reset_to: {name} must have shape ({num_robots},), "
                                 f"got {jnp.shape(value)}")
        key = jax.random.key(0) if key is None else key
        return self._reset_to_compiled(start, goal, present, params, key)

    def _reset_to(
        self, start: Array, goal: Array, present: Array, params: EnvParams, key: Array,
        spawn_present: Array | None = None, world: WorldDraw | None = None,
    ) -> tuple[Array, EnvState]:
        num_robots = self.max_agents
        if self.config.world is not None and world is None:  # reset_to: the params' map
            hp = params.humans
            world = WorldDraw(map=params.map, valid=jnp.asarray(True), values={
                name: jnp.float32(jnp.nan) for name in self.config.world.family.parameters},
                seed=jnp.uint32(0), humans=None if not self.config.world.human_radius else
                SpawnSlots(x=hp.spawn_x, y=hp.spawn_y, nodes=hp.spawn_nodes,
                           valid=hp.spawn_valid, node_valid=hp.node_valid))
        # Split only what is used: reset runs inside every auto-reset step.
        key_humans, key_zones, key_obs = key, key, key
        if self.config.uses_zones or self.config.observer.needs_key:
            key_humans, key_zones, key_obs = jax.random.split(key, 3)
        route = build_routes(params.map, jnp.asarray(start, jnp.int32),
                             jnp.asarray(goal, jnp.int32))
        x, y = route.x[:, 0], route.y[:, 0]
        heading = jnp.arctan2(route.y[:, 1] - y, route.x[:, 1] - x)
        zeros = jnp.zeros(num_robots, jnp.float32)
        robots = RobotState(
            x=x, y=y,
            kin=Kinematics(heading=heading, v_forward=zeros, v_lateral=zeros, omega=zeros,
                           steering=zeros),
            present=jnp.asarray(present, bool), succeeded=jnp.zeros(num_robots, bool),
            ended=jnp.zeros(num_robots, bool), parked=jnp.zeros(num_robots, bool),
            settle_steps=jnp.zeros(num_robots, jnp.int32),
        )
        no = jnp.zeros(num_robots, bool)
        none = jnp.zeros(num_robots, jnp.int32)
        # Pedestrians avoid the start of every robot in spawn_present (default: the present).
        blockers = robots.present if spawn_present is None else jnp.asarray(spawn_present, bool)
        humans = spawn_humans(key_humans, self.config.humans, params.humans, params.map, x, y,
                              params.robots.radius, blockers)
        zones = start_zones(key_zones, route.x, route.y, x, y, params.robots.radius,
                            robots.present, self.config.tracked_zones(params.map.zone_rect))
        distance = route.goal_distance(x, y)
        state = EnvState(
            robots=robots, route=route, progress=zeros,
            touching_robot=no, touching_wall=no, touching_human=no,
            collisions=CollisionCounts(robot=none, wall=none, human=none),
            humans=humans,
            time=jnp.zeros((), jnp.int32),
            history=History.start(self.config.observer.history_length - 1, robots, distance),
            zones=zones,
            moved=jnp.zeros((self.config.enders.window, num_robots), jnp.float32),
            total_steps=jnp.zeros((), jnp.int32),
            held_action=(jnp.zeros((num_robots, self.config.action_dim), jnp.float32)
                         if self.config.action_mode == "continuous"
                         else jnp.full(num_robots, GO, jnp.int32)),
            world=world,
            next_level=(Level.unset(self.config.world.family.parameters)
                        if self.config.world is not None and self.config.world.levels
                        else None),
        )
        return self.observe(state, params, key_obs), state

    # ------------------------------------------------------------------ step
    def step(
        self, key: Array, state: EnvState, actions: Array, params: EnvParams
    ) -> tuple[Array, EnvState, Array, Array, Array, dict]:
        """Step, and reset once every present robot is done.

        Returns ``obs [R, D], state, reward [R], terminated [R], truncated [R], info``. When the
        episode ends, ``obs``/``state`` are the new episode's, and ``info["final_observation"]``,
        ``info["final_robots"]``, ``info["final_collisions"]`` and ``info["final_time"]`` (steps)
        hold the ended episode's; ``info["episode_done"]`` says whether it ended.

        Concrete ``actions`` with a NaN or infinite continuous value, or a GO/STOP action other
        than 0 or 1, are an error naming the robot slot (:func:`reject_invalid_actions`);
        inside ``jit`` such an action is replaced by the neutral one (a zero command, STOP)
        and flagged in ``info["invalid_action"] [R]``.
        """
        reject_invalid_actions(actions, self.config.action_mode == "continuous")
        return self._step_compiled(key, state, actions, params)

    def _step(
        self, key: Array, state: EnvState, actions: Array, params: EnvParams
    ) -> tuple[Array, EnvState, Array, Array, Array, dict]:
        key_step, key_reset = jax.random.split(key)
        obs, next_state, reward, terminated, truncated, info = self._step_env(
            key_step, state, actions, params
        )
        episode_done = jnp.all(~next_state.robots.present | terminated | truncated)
        reset_obs, reset_state = self._reset(key_reset, params, level=state.next_level)
        info["episode_done"] = episode_done
        info["final_observation"] = obs
        info["final_robots"] = next_state.robots
        info["final_collisions"] = next_state.collisions
        info["final_time"] = next_state.time
        obs = jnp.where(episode_done, reset_obs, obs)
        next_state = jax.tree.map(
            lambda fresh, old: jnp.where(episode_done, fresh, old), reset_state, next_state
        )
        next_state = next_state.replace(total_steps=state.total_steps + 1)  # not reset
        return obs, next_state, reward, terminated, truncated, info

    def step_batch(
        self, keys: Array, states: EnvState, actions: Array, params: EnvParams,
        reset_chunk: int | None = None,
    ) -> tuple[Array, EnvState, Array, Array, Array, dict]:
        """:meth:`step` over a batch of ``N`` environments: the same returns, with a leading
        ``[N]`` axis, as ``jax.vmap(env.step, in_axes=(0, 0, 0, None))(keys, states, actions,
        params)``, bitwise, at a lower cost.

        ``vmap(step)`` samples a new episode for every environment at every step and keeps it
        only where the episode ended (a ``where`` cannot skip work); here the new episodes are
        sampled for the environments whose episode ended alone, ``reset_chunk`` of them at a
        time in a ``while_loop`` that runs ``ceil(ended / reset_chunk)`` times
        (:func:`sgjax.kernels.row_chunks.update_flagged_rows`; default ``reset_chunk``:
        ``max(8, ceil(N / 16))``). Each environment's new episode comes from its own key, as in
        :meth:`step`, so which ones share a chunk changes nothing.

        ``keys [N]`` (or ``[N, 2]`` raw keys), ``states`` with a leading ``[N]`` axis,
        ``actions [N, R]`` (GO/STOP) or ``[N, R, A]`` (continuous); ``params`` shared.
        """
        reject_invalid_actions(actions, self.config.action_mode == "continuous")
        if reset_chunk is not None and (not isinstance(reset_chunk, int) or reset_chunk < 1):
            raise ValueError(f"step_batch: reset_chunk must be a positive int, got {reset_chunk!r}")
        return self._step_batch_compiled(keys, states, actions, params, reset_chunk)

    def _step_batch(
        self, keys: Array, states: EnvState, actions: Array, params: EnvParams,
        reset_chunk: int | None,
    ) -> tuple[Array, EnvState, Array, Array, Array, dict]:
        num_envs = keys.shape[0]
        chunk = min(reset_chunk, num_envs) if reset_chunk else chunk_size(num_envs)
        both = jax.vmap(jax.random.split)(keys)  # as _step splits each environment's key
        key_step, key_reset = both[:, 0], both[:, 1]
        obs, next_state, reward, terminated, truncated, info = jax.vmap(
            self._step_env, in_axes=(0, 0, 0, None))(key_step, states, actions, params)
        episode_done = jnp.all(~next_state.robots.present | terminated | truncated, axis=1)
        info["episode_done"] = episode_done
        info["final_observation"] = obs
        info["final_robots"] = next_state.robots
        info["final_collisions"] = next_state.collisions
        info["final_time"] = next_state.time

        def reset_some(index: Array, carry: tuple) -> tuple:
            """Reset the ended environments ``index [chunk]`` (unused places point past the
            batch and are dropped)."""
            obs, state = carry
            ended = jnp.minimum(index, num_envs - 1)
            levels = (None if states.next_level is None  # a trainer's chosen worlds, if any
                      else jax.tree.map(lambda x: x[ended], states.next_level))
            fresh_obs, fresh = jax.vmap(
                lambda k, lv: self._reset(k, params, level=lv))(key_reset[ended], levels)
            rows = index[:, None]
            obs = _set_rows(obs, rows, fresh_obs)
            state = jax.tree.map(lambda old, new: _set_rows(old, rows, new), state, fresh)
            return obs, state

        obs, next_state = update_flagged_rows(episode_done, chunk, reset_some, (obs, next_state))
        next_state = next_state.replace(total_steps=states.total_steps + 1)  # not reset
        return obs, next_state, reward, terminated, truncated, info

    def step_env(
        self, key: Array, state: EnvState, actions: Array, params: EnvParams
    ) -> tuple[Array, EnvState, Array, Array, Array, dict]:
        """One step without auto-reset (same returns as :meth:`step`), phase by phase; each
        phase runs under a ``jax.named_scope`` of its name, so profiles show where time goes.

        ``info["reward_terms"]`` holds each reward term's weighted value ``[R]`` (and the stuck
        penalty under ``"stuck"`` when that ender is on); ``info["was_active"] [R]`` says which
        robots were active at the start of the step (they alone were rewarded; settling robots
        move too), ``info["arrived"] [R]`` which arrived during it, ``info["collision_*"] [R]``
        what they touched; ``info["invalid_action"] [R]`` which robots' new actions were invalid
        and replaced by the neutral action (see :meth:`step`); ``info["neighbor_overflow"]``
        (int32 scalar) how many bodies a full neighbour cell list left out (0 without cell
        lists: ``HumanConfig.neighbor_range``).
        """
        reject_invalid_actions(actions, self.config.action_mode == "continuous")
        return self._step_env_compiled(key, state, actions, params)

    def _step_env(
        self, key: Array, state: EnvState, actions: Array, params: EnvParams
    ) -> tuple[Array, EnvState, Array, Array, Array, dict]:
        cfg, layout = self.config, self.config.layout
        params = self.params_in(state, params)
        key_humans, key_obs = jax.random.split(key) if cfg.observer.needs_key else (key, key)
        with jax.named_scope("decode_actions"):
            # at a decision step the new actions, else each robot's held one
            decided = self.decides(state)
            fresh = self._checked(actions)
            continuous = cfg.action_mode == "continuous"
            invalid = decided & invalid_actions(fresh, continuous)
            neutral = jnp.zeros_like(fresh) if continuous else jnp.full_like(fresh, STOP)
            fresh = jnp.where(invalid[:, None] if continuous else invalid, neutral, fresh)
            actions = jnp.where(decided, fresh, state.held_action)
            commands = self._commands(state, actions, params)
        with jax.named_scope("pedestrian_waypoints"):
            humans = advance_waypoints(key_humans, cfg.humans, params.humans, params.map,
                                       state.humans)
        with jax.named_scope("physics"):
            robots, humans, contacts = physics.advance(
                state.robots, humans, commands, params, cfg.substeps, cfg.contact_passes,
                cfg.humans)
        with jax.named_scope("bookkeeping"):
            moved = self._book(state, robots, humans, contacts, params)
        with jax.named_scope("enders"):
            # one term input for the step; terms that draw random numbers get their own keys
            inputs = TermInput(prev=state, state=moved, actions=actions, params=params,
                               key=jax.random.fold_in(key_obs, 1), layout=layout)
            outcome, ender_rewards = cfg.enders(inputs)
            next_state = self._conclude(state, moved, outcome, cfg.arrived, cfg.ended == "park",
                                        params.dt).replace(held_action=actions)
        with jax.named_scope("rewards"):
            reward, reward_terms = cfg.rewarder(
                inputs.replace(state=next_state, key=jax.random.fold_in(key_obs, 2)))
            was_active = state.robots.active
            reward = reward + jnp.where(was_active, outcome.reward, 0.0)
            reward_terms.update({k: jnp.where(was_active, v, 0.0)
                                 for k, v in ender_rewards.items()})
        with jax.named_scope("observations"):
            obs = self.observe(next_state, params, key_obs)
        present, finished = state.robots.present, next_state.robots.finished
        terminated = present & finished
        truncated = present & ~finished & outcome.truncated
        info = {
            "was_active": was_active,
            "collision_robot": contacts.robot,
            "collision_wall": contacts.wall,
            "collision_human": contacts.human,
            "neighbor_overflow": contacts.neighbor_overflow,
            "arrived": next_state.robots.succeeded & ~state.robots.succeeded,
            "reward_terms": reward_terms,
            "decided": decided,
            "invalid_action": invalid,
        }
        return obs, next_state, reward, terminated, truncated, info

    def _book(self, state: EnvState, robots: RobotState, humans: HumanState,
              contacts: physics.Contacts,
              params: EnvParams) -> EnvState:
        """The state after the motion: arrivals, route progress, collision onsets, the stuck
        detector's window, history and zone books (the enders have not spoken yet)."""
        active = state.robots.active
        x, y = robots.x, robots.y
        arrived = active & (state.route.goal_distance(x, y) < params.goal_tolerance)
        progress = jnp.where(state.robots.moving,
                             route_progress(state.route, x, y, state.progress), state.progress)
        counts = state.collisions
        collisions = CollisionCounts(
            robot=counts.robot + (contacts.robot & ~state.touching_robot).astype(jnp.int32),
            wall=counts.wall + (contacts.wall & ~state.touching_wall).astype(jnp.int32),
            human=counts.human + (contacts.human & ~state.touching_human).astype(jnp.int32),
        )
        time = state.time + 1
        moved_now = jnp.where(active, safe_norm(x - state.robots.x, y - state.robots.y), 0.0)
        window = state.moved.shape[0]
        moved = state.moved.at[state.time % window].set(moved_now) if window else state.moved
        return EnvState(
            robots=robots.replace(succeeded=state.robots.succeeded | arrived),
            route=state.route,
            progress=progress,
            touching_robot=contacts.robot,
            touching_wall=contacts.wall,
            touching_human=contacts.human,
            collisions=collisions,
            humans=humans,
            time=time,
            history=state.history.push(state.robots, state.goal_distance),
            zones=update_zones(state.zones, x, y, params.robots.radius,
                               self.config.tracked_zones(params.map.zone_rect), time),
            moved=moved,
            total_steps=state.total_steps + 1,
            held_action=state.held_action,
            world=state.world,
            next_level=state.next_level,
        )

    @staticmethod
    def _conclude(state: EnvState, moved: EnvState, outcome: Outcome, arrived: str,
                  park_ended: bool, dt: Array) -> EnvState:
        """Robots the enders terminate without success end (absorbing) in the next state; the
        robots that finish this step park where they are if their kind parks (their kinematic
        state stays frozen as it was; as bodies they are at rest: ``RobotState.body_velocity``),
        or, arrived under ``"settle"``, start settling; settling robots within
        ``SETTLE_TOLERANCE`` of their goal, or settling for ``SETTLE_SECONDS``, park."""
        r = moved.robots
        was_active = state.robots.active
        ended = r.ended | (outcome.terminated & was_active & ~r.succeeded)
        arrived_now = was_active & r.succeeded
        newly = (arrived_now & (arrived == "park")) | (was_active & ended & park_ended)
        steps = r.settle_steps
        if arrived == "settle":
            settling = r.settling | arrived_now
            steps = steps + settling.astype(jnp.int32)
            settled = settling & ((moved.route.goal_distance(r.x, r.y) < SETTLE_TOLERANCE)
                                  | (steps.astype(jnp.float32) * dt >= SETTLE_SECONDS))
            newly = newly | settled
        return moved.replace(robots=r.replace(ended=ended, parked=r.parked | newly,
                                              settle_steps=steps))

    def _checked(self, actions: Array) -> Array:
        """``actions`` as the step takes them (``[R]`` int32 GO/STOP or ``[R, A]`` float32), or
        an error naming the expected shape and type."""
        cfg = self.config
        actions = jnp.asarray(actions)
        if cfg.action_mode == "continuous":
            expected = (self.max_agents, cfg.action_dim)
            if actions.shape != expected:
                raise ValueError(f"actions: expected shape {expected} (robots, action dim) for "
                                 f"continuous actions, got {actions.shape}")
            return actions.astype(jnp.float32)
        if actions.shape != (self.max_agents,):
            raise ValueError(f"actions: expected shape ({self.max_agents},) of GO(0)/STOP(1) "
                             f"ints, got {actions.shape}")
        if not jnp.issubdtype(actions.dtype, jnp.integer):
            raise ValueError(f"actions: expected integers GO(0)/STOP(1), got dtype {actions.dtype}")
        return actions.astype(jnp.int32)

    def decides(self, state: EnvState) -> Array:
        """Whether a step from ``state`` reads new actions (bool scalar): always with
        ``decision_period`` 1, else when the episode time is a multiple of it."""
        period = self.config.decision_period
        return jnp.asarray(True) if period == 1 else state.time % period == 0

    def _commands(self, state: EnvState, actions: Array, params: EnvParams) -> Commands:
        """Decode checked actions into per-robot commands: continuous actions directly, GO
        through the local planner, STOP as braking at the deceleration limit. Settling robots
        (``arrived="settle"``) ignore their actions: under GO/STOP they follow the planner no
        faster than they can stop at their goal point; under continuous actions (where the
        planner is not run) they drive straight onto it
        (:func:`sgjax.dynamics.planner.approach`)."""
        cfg, rp, robots = self.config, params.robots, state.robots
        settle = cfg.arrived == "settle"
        if cfg.action_mode == "continuous":
            chosen = Commands(*decode_continuous(actions, rp, cfg.action_dim))
            if not settle:
                return chosen
            forward, turn = approach(params.planner, rp, robots.x, robots.y, robots.heading,
                                     robots.kin.v_forward, params.dt, state.route.goal_x,
                                     state.route.goal_y)
            return Commands(jnp.where(robots.settling, forward, chosen.forward),
                            jnp.where(robots.settling, 0.0, chosen.lateral),
                            jnp.where(robots.settling, turn, chosen.turn))
        carrot_x, carrot_y = carrot_point(params.planner, state.route, state.progress)
        speed_limit = None
        if settle:  # no faster than a settling robot can stop at its goal point
            to_goal = jnp.maximum(state.route.goal_distance(robots.x, robots.y), 1e-12)
            speed_limit = jnp.where(robots.settling, jnp.sqrt(2.0 * rp.max_decel * to_goal),
                                    rp.max_speed)
        forward, turn = plan(
            cfg.planner, params.planner, rp, params.map, robots.x, robots.y, robots.heading,
            robots.kin.v_forward, params.dt, robots.in_world, carrot_x, carrot_y,
            velocity=robots.body_velocity_xy, bodies=self._pedestrian_bodies(state, params),
            speed_limit=speed_limit,
        )
        go = (actions == GO) | robots.settling
        # STOP: brake to rest; Ackermann robots hold their steering.
        turn = jnp.where(go, turn, jnp.where(rp.model == ACKERMANN, robots.kin.steering, 0.0))
        return Commands(jnp.where(go, forward, 0.0), jnp.zeros_like(forward), turn)

    def _pedestrian_bodies(
        self, state: EnvState, params: EnvParams
    ) -> tuple[Array, Array, Array, Array, Array, Array] | None:
        """Pedestrians as moving discs ``(x, y, vx, vy, radius, active)`` for the planner (None
        if there are none)."""
        if not self.config.humans.max_humans:
            return None
        h = state.humans
        return h.x, h.y, h.vx, h.vy, params.humans.radius, h.active

    # ------------------------------------------------------------ observation
    def observe(self, state: EnvState, params: EnvParams, key: Array | None = None) -> Array:
        """Observations ``[R, D]`` from the configured terms (zeros for robots not in the
        episode); ``key`` feeds noisy terms (lidar noise), default ``jax.random.key(0)``."""
        key = jax.random.key(0) if key is None else key
        params = self.params_in(state, params)
        return self.config.observer(TermInput.observing(state, params, self.config.layout, key))

    # Compiled entry points: an eager call runs one compiled program instead of dispatching (and
    # compiling) thousands of primitives one by one; inside an outer jit, vmap, scan or grad
    # they are inlined; under ``jax.disable_jit()`` they run op by op.
    _reset_compiled = jax.jit(_reset, static_argnums=0)
    _reset_to_compiled = jax.jit(_reset_to, static_argnums=0)
    _reset_subset_compiled = jax.jit(_reset, static_argnums=0)
    _step_compiled = jax.jit(_step, static_argnums=0)
    _step_env_compiled = jax.jit(_step_env, static_argnums=0)
    _step_batch_compiled = jax.jit(_step_batch, static_argnums=(0, 5))


def invalid_actions(actions: Array, continuous: bool) -> Array:
    """``[..., R]`` bool: robots whose action the step cannot take: a continuous action with a
    NaN or infinite component (``actions [..., R, A]``), a GO/STOP action other than GO (0) or
    STOP (1) (``actions [..., R]``)."""
    if continuous:
        return ~jnp.all(jnp.isfinite(actions), axis=-1)
    return (actions != GO) & (actions != STOP)


def reject_invalid_actions(actions: Any, continuous: bool, where: str = "actions") -> None:
    """Outside ``jit``: raise ``ValueError`` naming the first robot slot (and batch index) whose
    action :func:`invalid_actions` refuses, and how many are; traced actions (inside ``jit``,
    where the step neutralises and flags them instead) pass unchecked."""
    if isinstance(actions, jax.core.Tracer):
        return
    values = np.asarray(actions)
    if continuous:
        if values.ndim < 2:
            return  # a shape error, reported by the step's own check
        bad = ~np.all(np.isfinite(values), axis=-1)
        rule = "continuous actions must be finite"
    else:
        bad = (values != GO) & (values != STOP)
        rule = f"GO/STOP actions are {GO} (GO) or {STOP} (STOP)"
    if not bad.any():
        return
    first = tuple(int(i) for i in np.argwhere(bad)[0])
    place = (f"robot slot {first[-1]}" if len(first) == 1 else
             f"robot slot {first[-1]} of batch index {first[:-1] if len(first) > 2 else first[0]}")
    more = f" (and {int(bad.sum()) - 1} more)" if bad.sum() > 1 else ""
    raise ValueError(f"{where}: {place} has action {values[first].tolist()}{more}; {rule}")
