"""The environment's datatypes: state, params and the static layout that terms read.

This module is a leaf of the environment: it imports only kernels (dynamics, maps, humans,
planner, zones, geometry), and every layer above (terms, the environment, evaluation) imports it.

Shape letters, used in every docstring of the package:

* ``R``: robot slots (``Layout.max_agents``); ``H``: pedestrian slots (``Layout.max_humans``);
* ``D``: length of one robot's observation vector; ``K``: nearest others an observation lists;
* ``W``: steps of history an observation term reads; ``Z``: conflict zones on the map;
* ``L``: waypoints of a route; ``T``: steps of the stuck detector's window.

Robot slots, one vocabulary everywhere:

* **present** (``RobotState.present``): the slot takes part in this episode (the first
  ``params.num_agents`` slots that ``reset`` could place); absent slots are padding;
* **finished** (``RobotState.finished``): present and terminated, by arrival (``succeeded``) or
  by an ender (``ended``, e.g. a fatal collision); absorbing: reads no actions, reward 0 (a
  settling robot still moves);
* **active** (``RobotState.active``): present and not finished: it moves, is rewarded and can end;
* **settling** (``RobotState.settling``): arrived, and driven on to its goal point by its local
  planner (``make(arrived="settle")``, the default): a moving body that reads no actions and earns
  nothing, until it parks within ``sgjax.environment.env.SETTLE_TOLERANCE`` of the goal;
* **moving** (``RobotState.moving``): active or settling: what the physics moves;
* **parked** (``RobotState.parked``): finished and kept in the world at rest, a static body that
  the others plan around, collide with and observe (an arrived robot once it has settled, or at
  once where it arrived with ``arrived="park"``; ``ended="park"`` for robots an ender stopped).
  With ``"leave"`` a finished robot leaves the world instead;
* **in world** (``RobotState.in_world``): active, settling or parked: a body that others meet.

Units are SI throughout (m, s, rad; angles wrapped to (-pi, pi]).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.dynamics.limits import RobotParams
from sgjax.dynamics.models import Kinematics
from sgjax.dynamics.planner import PlannerParams
from sgjax.humans.pedestrians import HumanParams, HumanState
from sgjax.kernels.zone_books import ZoneState
from sgjax.maps.arrays import MapArrays
from sgjax.maps.sampling import Route

ACTION_MODES = ("go_stop", "continuous")
# What becomes of a finished robot: it stays at rest where it finished as a static body ("park")
# or leaves the world ("leave").
WORLD_SEMANTICS = ("park", "leave")
# What becomes of an arrived robot: the same two, or "settle" (SocialGym 2.0's behaviour: its
# local planner keeps driving it on to its goal point, where it parks; it is a moving body, not
# a learner, on the way).
ARRIVED_SEMANTICS = ("park", "settle", "leave")
GO, STOP = 0, 1  # the two GO/STOP actions


@dataclasses.dataclass(frozen=True)
class Layout:
    """The static sizes that terms and policies need (changing one recompiles).

    ``action_dim`` is 2 ``(forward, turn)`` or 3 ``(forward, lateral, turn)`` for continuous
    actions (3 when the team has an omnidirectional robot); GO/STOP actions are one int each.
    """

    max_agents: int  # R
    max_humans: int = 0  # H
    num_zones: int = 0  # Z
    action_mode: str = "go_stop"
    action_dim: int = 2


@struct.dataclass
class RobotState:
    """Robots, each field ``[R]``. Public: ``position``, ``heading``, ``velocity``, ``active``,
    ``in_world``."""

    x: Array  # m, world
    y: Array  # m, world
    kin: Kinematics
    present: Array  # bool: takes part in this episode
    succeeded: Array  # bool: reached its goal (absorbing)
    ended: Array  # bool: terminated by an ender without success, e.g. a collision (absorbing)
    parked: Array  # bool: finished and kept in the world at rest as a static body
    settle_steps: Array  # int32: steps an arrived robot spent settling on its goal point

    @property
    def position(self) -> Array:
        """World position ``[R, 2]`` (m)."""
        return jnp.stack([self.x, self.y], axis=-1)

    @property
    def heading(self) -> Array:
        """Heading ``[R]`` (rad, in (-pi, pi])."""
        return self.kin.heading

    @property
    def velocity(self) -> Array:
        """World-frame velocity ``[R, 2]`` (m/s)."""
        c, s = jnp.cos(self.kin.heading), jnp.sin(self.kin.heading)
        vf, vl = self.kin.v_forward, self.kin.v_lateral
        return jnp.stack([vf * c - vl * s, vf * s + vl * c], axis=-1)

    @property
    def body_velocity(self) -> Array:
        """World-frame velocity ``[R, 2]`` (m/s) of each robot as a body: zero once parked (at
        rest), else its velocity (a robot that left the world is masked out wherever bodies
        are read)."""
        return jnp.where(self.parked[:, None], 0.0, self.velocity)

    @property
    def body_velocity_xy(self) -> tuple[Array, Array]:
        """:attr:`body_velocity` as its x and y components, ``[R]`` each (m/s): for kernels that
        work on components (the planner), where XLA then drops the ``[R, 2]`` stack."""
        return tuple(jnp.where(self.parked, 0.0, self.velocity[:, i]) for i in (0, 1))

    @property
    def finished(self) -> Array:
        """``[R]`` bool: terminated (arrived, or ended by an ender)."""
        return self.succeeded | self.ended

    @property
    def active(self) -> Array:
        """``[R]`` bool: present and not finished."""
        return self.present & ~self.finished

    @property
    def settling(self) -> Array:
        """``[R]`` bool: arrived and still driven on to its goal point by its planner (only
        ``arrived="settle"`` counts settling steps), not yet parked."""
        return (self.settle_steps > 0) & ~self.parked

    @property
    def moving(self) -> Array:
        """``[R]`` bool: moves this step: active, or settling on its goal point."""
        return self.active | self.settling

    @property
    def in_world(self) -> Array:
        """``[R]`` bool: a body in the world (active, settling, or parked where it finished)."""
        return self.active | self.settling | self.parked


@struct.dataclass
class CollisionCounts:
    """Collision onsets per robot since the episode began, ``[R]`` int32."""

    robot: Array
    wall: Array
    human: Array


@struct.dataclass
class History:
    """Past values for observation terms with a history: ``[W - 1, R]`` each, row 0 the step
    before the current one (``W = observer.history_length``; the current values are read from
    the state itself, so with W = 1 the arrays are empty). At reset every row holds the initial
    value."""

    vx: Array  # m/s, world frame
    vy: Array
    v_forward: Array  # m/s, body frame
    v_lateral: Array
    omega: Array  # rad/s
    goal_distance: Array  # m, straight line

    @staticmethod
    def of(robots: RobotState, distance: Array) -> dict[str, Array]:
        """This step's row: ``{field: [R]}`` from the robots and their goal distances (m)."""
        v = robots.velocity
        k = robots.kin
        return {"vx": v[:, 0], "vy": v[:, 1], "v_forward": k.v_forward, "v_lateral": k.v_lateral,
                "omega": k.omega, "goal_distance": distance}

    @classmethod
    def start(cls, length: int, robots: RobotState, distance: Array) -> History:
        """``length`` rows, each the robots' values now."""
        now = cls.of(robots, distance)
        return cls(**{n: jnp.broadcast_to(v, (length,) + v.shape) for n, v in now.items()})

    def push(self, robots: RobotState, distance: Array) -> History:
        """Shift the rows back one step and put the robots' values now in row 0."""
        if not self.goal_distance.shape[0]:
            return self
        now = self.of(robots, distance)
        return History(**{n: jnp.concatenate([v[None], getattr(self, n)[:-1]], axis=0)
                          for n, v in now.items()})


@struct.dataclass
class EnvState:
    """One episode's state."""

    robots: RobotState  # [R]
    route: Route  # [R, L] waypoints from each robot's start to its goal
    progress: Array  # [R] m along the route
    touching_robot: Array  # [R] bool, at the last step (for onsets)
    touching_wall: Array  # [R] bool
    touching_human: Array  # [R] bool
    collisions: CollisionCounts
    humans: HumanState  # pedestrians [H]
    time: Array  # int32 steps since reset
    history: History  # [W - 1, R] past velocities and goal distances
    zones: ZoneState  # [R, Z] conflict-zone bookkeeping
    moved: Array  # [T, R] m travelled per step over the stuck detector's window (ring buffer)
    total_steps: Array  # int32 steps since the first reset, kept across auto-resets (schedules)
    # [R] int32 GO/STOP or [R, A] float32: each robot's action in force (the last one read;
    # EnvConfig.decision_period)
    held_action: Array
    # the generated world this episode plays in (sgjax.environment.worlds.WorldDraw), or None on
    # a fixed map (no leaves: nothing traced)
    world: Any = None
    # the world of the next episode, when a trainer picks it (sgjax.environment.worlds.Level,
    # on a source with levels); None otherwise
    next_level: Any = None

    @property
    def goal_distance(self) -> Array:
        """``[R]`` straight-line distance from each robot to its goal (m)."""
        return self.route.goal_distance(self.robots.x, self.robots.y)


@struct.dataclass
class RewardParams:
    """Reward-term weights by term name: ``{name: sgjax.rewards.Schedule}`` (a pytree of
    params, so a ``vmap`` over weights is an ablation)."""

    weights: dict[str, Any]


@struct.dataclass
class EnvParams:
    """Everything physical; a pytree, so ``vmap`` over it is a sweep."""

    robots: RobotParams  # [R] per-slot limits and radius
    map: MapArrays
    planner: PlannerParams
    reward: RewardParams  # weight schedules by reward-term name
    humans: HumanParams
    num_agents: Array  # int32 scalar: robots that take part in an episode (the most, see below)
    dt: Array  # s per step
    max_steps: Array  # int32: truncation after this many steps
    goal_tolerance: Array  # m
    # int32 scalar: 0 (off): every episode has num_agents robots; n >= 1: each episode draws
    # its robot count uniformly from [min(n, num_agents), num_agents]
    min_agents: Array


def episode_params(state: EnvState, params: EnvParams) -> EnvParams:
    """The params an episode plays under: ``params`` with the episode's generated world as its
    map and its pedestrians' spawn slots (``state.world``, ``sgjax.environment.worlds``), or
    ``params`` itself on a fixed map.
    Anything that reads the map beside the step (a controller, a metric) reads it from these."""
    return params if state.world is None else state.world.params_of(params)
