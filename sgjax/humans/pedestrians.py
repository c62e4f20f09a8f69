"""Pedestrians: state, params, spawning, waypoint following and one physics sub-step.

Pedestrians are ``[H]`` arrays padded to the static ``HumanConfig.max_humans``; the first
``HumanParams.num_humans`` of them are ``active`` (a param: changing it does not recompile).
Each walks the navigation graph: it heads for ``target`` (a node row), the next node on the
shortest path to its ``goal``; on reaching the goal it takes a new one (a random node, or the
node it came from: SocialGym's back-and-forth walk), so crowds persist for the whole episode.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import jax
import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.humans.forces import (
    SocialForceParams,
    cap_speed,
    desired_force,
    exponential_wall_force,
    helbing_interaction,
    helbing_wall_force,
    moussaid_interaction,
    unit,
)
from sgjax.humans.groups import GroupParams, group_forces, spawn_beside_leaders
from sgjax.humans.hsfm import HsfmParams, hsfm_update
from sgjax.humans.near_walls import wall_offsets
from sgjax.humans.neighbors import (
    SPAN,
    Each,
    Pairs,
    body_grid,
    cell_capacity,
    map_pairs,
    uses_grid,
)
from sgjax.humans.orca_model import OrcaParams, orca_forces
from sgjax.humans.replay import REPLAY_MODES, Recording, ReplayState, start_replay, walking_target
from sgjax.humans.slots import SPAWN_JITTER, SPAWN_MARGIN
from sgjax.kernels.contacts import clamp_to_walls, uses_broad_phase
from sgjax.kernels.geometry import (
    polynomial_atan2,
    safe_norm,
    swept_disc_segment_toi,
    wrap_angle,
)
from sgjax.kernels.row_chunks import chunk_size, update_flagged_rows
from sgjax.maps.arrays import MapArrays

FORCE_MODELS = ("moussaid", "helbing", "orca", "hsfm")
WALL_MODELS = ("segments", "points")
GOAL_MODES = ("random", "return", "routes")


@dataclasses.dataclass(frozen=True)
class HumanConfig:
    """Static pedestrian settings (changing them recompiles).

    ``force_model``: ``"moussaid"`` (Moussaid 2009 interaction, exponential obstacle term) or
    ``"helbing"`` (Helbing-Molnar 1995 potentials with a field of view) or ``"orca"``
    (optimal reciprocal collision avoidance, :mod:`sgjax.humans.orca_model`, among the
    ``orca_neighbors`` nearest bodies and the ``orca_walls`` nearest walls) or ``"hsfm"`` (the
    headed social force model, :mod:`sgjax.humans.hsfm`: a heading turned by a torque).
    ``wall_model`` (Moussaid only): ``"segments"`` sums the obstacle term over each wall's nearest
    point; ``"points"`` sums it over points sampled along the walls, as PySocialForce does.
    ``goal_mode``: ``"random"`` (a new random node at each goal), ``"return"`` (walk back), or
    ``"routes"`` (start at a route's start, walk to its goal and back: the map's
    ``pedestrian_groups``, else its robot groups; the crowd scenarios use it).
    ``neighbor_range`` (m): bodies and walls at least this far from a pedestrian do not act on
    it (ORCA: RVO2's ``neighborDist``); ``None``, every body and wall does (the laws as
    published: none of them has a range). On a building floor the walls within it come from
    the map's wall grid (:mod:`sgjax.humans.near_walls`). ``neighbor_search``: with a range,
    find the bodies within it through cell lists of half a range per side (``"grid"``), over
    every body (``"all"``), or through the lists from
    :data:`sgjax.humans.neighbors.GRID_FROM_HUMANS` pedestrians on (``"auto"``: where they are
    faster); both give the same forces. ``cell_capacity``: bodies listed per
    cell (0: a density of 6 per m^2, :func:`sgjax.humans.neighbors.cell_capacity`); bodies
    beyond it are counted in ``info["neighbor_overflow"]``.
    """

    max_humans: int = 0
    force_model: str = "moussaid"
    wall_model: str = "segments"
    goal_mode: str = "random"
    orca_neighbors: int = 10  # CrowdNav's ORCA max_neighbors
    orca_walls: int = 4
    neighbor_range: float | None = None
    neighbor_search: str = "auto"
    cell_capacity: int = 0
    replay: str | None = None

    def __post_init__(self):
        for name, allowed in (("force_model", FORCE_MODELS), ("wall_model", WALL_MODELS),
                              ("goal_mode", GOAL_MODES)):
            value = getattr(self, name)
            if value not in allowed:
                raise ValueError(f"HumanConfig.{name} must be one of {allowed}, got {value!r}")
        if self.max_humans < 0:
            raise ValueError(f"HumanConfig.max_humans must be >= 0, got {self.max_humans}")
        for name in ("orca_neighbors", "orca_walls"):
            if getattr(self, name) < 1:
                raise ValueError(f"HumanConfig.{name} must be >= 1, got {getattr(self, name)}")
        if self.neighbor_range is not None and not self.neighbor_range > 0.0:
            raise ValueError(f"HumanConfig.neighbor_range must be > 0 m or None, got "
                             f"{self.neighbor_range}")
        if self.cell_capacity < 0:
            raise ValueError(f"HumanConfig.cell_capacity must be >= 0, got "
                             f"{self.cell_capacity}")
        if self.replay is not None and self.replay not in REPLAY_MODES:
            raise ValueError(f"HumanConfig.replay must be one of {REPLAY_MODES} or None, got "
                             f"{self.replay!r}")
        uses_grid(self.neighbor_range, self.neighbor_search, self.max_humans)  # checks both

    @property
    def uses_grid(self) -> bool:
        """Whether pedestrians find the bodies near them through cell lists (static)."""
        return uses_grid(self.neighbor_range, self.neighbor_search, self.max_humans)

    def each(self, m: MapArrays) -> Each:
        """How a force model meets the bodies on map ``m`` under this configuration:
        ``each(fn, bx, by, body_weight, *per_pedestrian)`` (:data:`sgjax.humans.neighbors.Each`;
        the first ``max_humans`` bodies are the pedestrians) runs
        :func:`sgjax.humans.neighbors.map_pairs` over every body or through cell lists."""
        cell = self.neighbor_range / SPAN if self.neighbor_range else 0.0
        grid = body_grid(m, cell) if self.uses_grid else None
        capacity = self.cell_capacity or (cell_capacity(cell) if cell else 0)
        num = self.max_humans

        def each(fn: Callable[..., tuple[Array, ...]], bx: Array, by: Array,
                 body_weight: Array, *per_pedestrian: Array) -> tuple[tuple[Array, ...], Array]:
            return map_pairs(fn, bx[:num], by[:num], bx, by, body_weight, per_pedestrian,
                             self.neighbor_range, grid, capacity)

        return each


@struct.dataclass(kw_only=True)
class HumanParams:
    """Pedestrian params (a pytree; keyword arguments only). ``spawn_*`` and ``wall_points_*``
    are compiled by ``sgjax.make`` for the map and radius; the rest may be changed or batched
    freely. The defaults of the constants are the pedestrians of ``socialnav.md`` B1: desired
    speeds N(1.34, 0.26) m/s clipped to [0.5, 2.0], a 1.3x speed cap."""

    num_humans: Array  # int32 scalar: active pedestrians in an episode
    radius: Array  # m (scalar); spawn slots were laid out for the value given to make()
    speed_mean: Array | float = 1.34  # m/s: desired speeds ~ N(mean, std) clipped to [min, max]
    speed_std: Array | float = 0.26  # m/s
    speed_min: Array | float = 0.5  # m/s
    speed_max: Array | float = 2.0  # m/s
    # speed cap = factor x desired speed (PySocialForce: 1.3)
    max_speed_factor: Array | float = 1.3
    waypoint_radius: Array | float = 0.75  # m: a waypoint counts as reached this close
    # How strongly robots repel pedestrians, relative to a pedestrian: twice, as the Moussaid
    # law ignores body sizes and at weight 1 pedestrians graze a standing robot
    # (tests/kernels/test_humans.py). pedsim gets the same effect by scaling a robot's distance
    # by robotPosDiffScalingFactor = 1.5. 0: pedestrians that do not see robots.
    robot_weight: Array | float = 2.0
    forces: SocialForceParams = SocialForceParams()
    spawn_x: Array  # [S] m: spawn slots
    spawn_y: Array
    spawn_nodes: Array  # [S, 2] int32: ends of the graph edge beside each slot
    wall_points_x: Array  # [P] m: sampled wall points (wall_model "points"; else empty)
    wall_points_y: Array
    orca: OrcaParams = OrcaParams()  # the "orca" model's constants
    hsfm: HsfmParams = HsfmParams()  # the "hsfm" model's constants
    groups: GroupParams | None = None  # who walks with whom, and the group forces
    route_start: Array | None = None  # [P] int32 node rows: pedestrian routes ("routes" mode)
    route_goal: Array | None = None  # [P] int32
    # a generated world's masks (the episode's, set at reset): which spawn slots are slots
    # [S] and which node rows are nodes [N] (random goals are drawn among them); None: all
    spawn_valid: Array | None = None
    node_valid: Array | None = None
    # replayed people (HumanConfig.replay): the recording's windows, how long a person a
    # robot touched stands (s, "pause"; SocNavBench's collision_cooldown_amnt) and the body gap
    # to a robot (m) that hands a person over to the force model ("handover")
    recording: Recording | None = None
    pause_seconds: Array | float = 1.0
    handover_radius: Array | float = 1.5


@struct.dataclass
class HumanState:
    """Pedestrians, each field ``[H]``. Public: ``position``, ``velocity``, ``active``."""

    x: Array  # m, world
    y: Array
    vx: Array  # m/s, world
    vy: Array
    target: Array  # int32 node row: next waypoint
    goal: Array  # int32 node row
    origin: Array  # int32 node row: where the current walk began (goal_mode "return")
    desired_speed: Array  # m/s
    active: Array  # bool: takes part in this episode
    heading: Array  # rad: the body's facing (HSFM turns it; other models face their motion)
    omega: Array  # rad/s: turn rate
    replay: ReplayState | None = None  # replayed people's clocks and books (HumanConfig.replay)

    @property
    def position(self) -> Array:
        """World position ``[H, 2]`` (m)."""
        return jnp.stack([self.x, self.y], axis=-1)

    @property
    def velocity(self) -> Array:
        """World velocity ``[H, 2]`` (m/s)."""
        return jnp.stack([self.vx, self.vy], axis=-1)


def _random_other_node(key: Array, current: Array, num_nodes: int,
                       valid: Array | None = None) -> Array:
    """A uniformly random node row different from ``current`` (when there are two or more),
    among the ``valid [N]`` rows when given (a generated world's nodes; ``current`` itself
    when no other is valid)."""
    if num_nodes < 2:
        return current
    if valid is None:
        offset = jax.random.randint(key, current.shape, 1, num_nodes)
        return (current + offset) % num_nodes
    other = valid[None, :] & (jnp.arange(num_nodes)[None, :] != current[:, None])
    pick = jax.random.categorical(key, jnp.where(other, 0.0, -jnp.inf), axis=-1)
    return jnp.where(jnp.any(other, axis=-1), pick, current).astype(current.dtype)


def no_humans() -> HumanState:
    """The pedestrians of a world without any (``max_humans == 0``): every field ``[0]``, of
    the dtype :func:`spawn_humans` gives it."""
    real, row = jnp.zeros((0,), jnp.float32), jnp.zeros((0,), jnp.int32)
    return HumanState(x=real, y=real, vx=real, vy=real, target=row, goal=row, origin=row,
                      desired_speed=real, active=jnp.zeros((0,), bool), heading=real,
                      omega=real)


def spawn_humans(
    key: Array, config: HumanConfig, hp: HumanParams, m: MapArrays,
    robot_x: Array, robot_y: Array, robot_radius: Array, robot_present: Array,
) -> HumanState:
    """Place ``hp.num_humans`` pedestrians at rest on distinct spawn slots clear of the robots'
    start bodies, with random goals and desired speeds. Robots are ``[R]`` arrays.

    A pedestrian is ``active`` only if a free slot was left for it; ``sgjax.make`` checks that
    ``max_humans`` always fit. Without pedestrians (``config.max_humans == 0``) nothing is
    computed: :func:`no_humans` (the paper's worlds compile and trace none of this).
    """
    if not config.max_humans:
        return no_humans()
    if config.replay:
        return replayed_humans(key, hp)
    num = config.max_humans
    num_nodes = m.node_x.shape[0]
    k_slot, k_jitter, k_goal, k_speed = jax.random.split(key, 4)
    reach = robot_radius[None, :] + hp.radius + SPAWN_JITTER * 1.5 + SPAWN_MARGIN
    gap_sq = (jnp.square(hp.spawn_x[:, None] - robot_x[None, :])
              + jnp.square(hp.spawn_y[:, None] - robot_y[None, :]))
    blocked = jnp.any(robot_present[None, :] & (gap_sq < jnp.square(reach)), axis=1)
    if hp.spawn_valid is not None:  # a generated world's lattice: only its slots
        blocked = blocked | ~hp.spawn_valid
    priority = jnp.where(blocked, -1.0, jax.random.uniform(k_slot, hp.spawn_x.shape))
    best, slot = jax.lax.top_k(priority, num)
    if config.goal_mode == "routes" and num:  # each on the free slot nearest its route's start
        k_slot, k_route = jax.random.split(k_slot)
        route = jax.random.randint(k_route, (num,), 0, hp.route_start.shape[0])
        start, route_goal = hp.route_start[route], hp.route_goal[route]
        slot = _nearest_free_slots(m.node_x[start], m.node_y[start], slot, priority >= 0.0,
                                   hp.spawn_x, hp.spawn_y)
    if hp.groups is not None:  # followers take the free slots nearest their leaders'
        free = (priority >= 0.0).at[slot].set(False)
        slot = spawn_beside_leaders(hp.groups.leader, slot, free, hp.spawn_x, hp.spawn_y)
    jitter = jax.random.uniform(k_jitter, (2, num), minval=-SPAWN_JITTER, maxval=SPAWN_JITTER)
    x, y = hp.spawn_x[slot] + jitter[0], hp.spawn_y[slot] + jitter[1]
    # Start toward whichever end of the slot's edge is on the shorter way to the goal.
    end_a, end_b = hp.spawn_nodes[slot, 0], hp.spawn_nodes[slot, 1]
    goal = _random_other_node(k_goal, end_a, num_nodes, hp.node_valid)
    if config.goal_mode == "routes" and num:
        goal = route_goal
    if hp.groups is not None:
        goal = goal[hp.groups.leader]  # a group shares its leader's goal

    def via(node: Array) -> Array:
        length = m.path_length[node, goal]
        return jnp.where(length >= 0.0, length + safe_norm(m.node_x[node] - x,
                                                           m.node_y[node] - y), jnp.inf)

    target = jnp.where(via(end_a) <= via(end_b), end_a, end_b)
    goal = jnp.where(jnp.isfinite(jnp.minimum(via(end_a), via(end_b))), goal, target)
    origin = target
    if config.goal_mode == "routes" and num:  # straight on from the route's start
        origin = start if hp.groups is None else start[hp.groups.leader]
        hop = m.next_hop[origin, goal]
        target = jnp.where(hop >= 0, hop, goal)
    speed = hp.speed_mean + hp.speed_std * jax.random.normal(k_speed, (num,))
    speed = jnp.clip(speed, hp.speed_min, hp.speed_max)
    if hp.groups is not None:
        speed = speed[hp.groups.leader]  # and walks at its pace
    active = (jnp.arange(num) < hp.num_humans) & (best >= 0.0)
    zeros = jnp.zeros(num, jnp.float32)
    heading = polynomial_atan2(m.node_y[target] - y, m.node_x[target] - x)
    return HumanState(x=x, y=y, vx=zeros, vy=zeros, target=target, goal=goal, origin=origin,
                      desired_speed=speed, active=active, heading=heading, omega=zeros)


def replayed_humans(key: Array, hp: HumanParams) -> HumanState:
    """The people of a random window of ``hp.recording`` at its first row (replay mode): each
    at their recorded position and velocity, active where the recording holds them, wanting
    their recorded mean speed; their node rows are unused (0)."""
    rec = hp.recording
    replay, (x, y, vx, vy, present) = start_replay(key, rec)
    rows = jnp.zeros(x.shape, jnp.int32)
    return HumanState(x=x, y=y, vx=vx, vy=vy, target=rows, goal=rows, origin=rows,
                      desired_speed=rec.speed[replay.window], active=present,
                      heading=polynomial_atan2(vy, vx), omega=jnp.zeros(x.shape, jnp.float32),
                      replay=replay)


def _nearest_free_slots(anchor_x: Array, anchor_y: Array, slot: Array, free: Array,
                        spawn_x: Array, spawn_y: Array) -> Array:
    """``[H]`` distinct slots: pedestrian ``i`` (in index order) takes the free slot nearest
    ``(anchor_x[i], anchor_y[i])`` (m); ``free`` ``[S]``: slots no robot blocks."""
    def place(i: Array, carry: tuple[Array, Array]) -> tuple[Array, Array]:
        out, used = carry
        gap = jnp.square(spawn_x - anchor_x[i]) + jnp.square(spawn_y - anchor_y[i])
        pick = jnp.argmin(jnp.where(free & ~used, gap, jnp.inf))
        return out.at[i].set(pick), used.at[pick].set(True)

    used = jnp.zeros(spawn_x.shape, bool)
    return jax.lax.fori_loop(0, slot.shape[0], place, (slot, used))[0]


def advance_waypoints(
    key: Array, config: HumanConfig, hp: HumanParams, m: MapArrays, humans: HumanState
) -> HumanState:
    """Move each pedestrian's target on once it is within ``waypoint_radius`` of it and the next
    waypoint is in plain view (its body can walk straight there without touching a wall), or
    once it stands on the target (within its radius); at the goal, pick the next goal
    (``goal_mode``). Without the view rule a pedestrian that turned early for a waypoint round a
    corner walked into the corner's wall. Without pedestrians (``config.max_humans == 0``)
    ``humans`` is returned as it is."""
    if not config.max_humans or config.replay:
        return humans
    tx, ty = m.node_x[humans.target], m.node_y[humans.target]
    distance = safe_norm(tx - humans.x, ty - humans.y)
    near = humans.active & (distance < hp.waypoint_radius)
    at_goal = near & (humans.target == humans.goal)
    if config.goal_mode in ("return", "routes"):
        fresh = humans.origin
    else:
        fresh = _random_other_node(key, humans.target, m.node_x.shape[0], hp.node_valid)
    fresh = jnp.where(m.path_length[humans.target, fresh] >= 0.0, fresh, humans.origin)
    goal = jnp.where(at_goal, fresh, humans.goal)
    if hp.groups is not None:
        goal = goal[hp.groups.leader]  # followers keep their leader's goal
    origin = jnp.where(at_goal, humans.target, humans.origin)
    hop = m.next_hop[humans.target, goal]
    # the view test decides only for pedestrians near a waypoint and not standing on it
    asks = near & ~(distance < hp.radius) & ~at_goal
    in_view = _next_in_view(hp, m, humans, hop, asks)
    reached = near & (in_view | (distance < hp.radius) | at_goal)
    target = jnp.where(reached & (hop >= 0), hop, humans.target)
    return humans.replace(target=target, goal=goal, origin=origin)


def _next_in_view(hp: HumanParams, m: MapArrays, humans: HumanState, hop: Array,
                  asks: Array) -> Array:
    """``[H]`` bool: whether each pedestrian's body can walk straight to node ``hop`` without
    touching a wall (swept disc against every wall: the way may be long, past any wall grid's
    reach). On a map of many walls (``kernels.contacts.uses_broad_phase``) only the
    pedestrians that ``asks`` flags are tested, a chunk at a time (``kernels.row_chunks``;
    the others read True: their answer is not used)."""

    def view(rows: Array) -> Array:
        x, y = humans.x[rows], humans.y[rows]
        toward_x, toward_y = m.node_x[hop[rows]] - x, m.node_y[hop[rows]] - y
        hits = swept_disc_segment_toi(x[:, None], y[:, None], toward_x[:, None],
                                      toward_y[:, None], hp.radius, m.wall_x1, m.wall_y1,
                                      m.wall_x2, m.wall_y2)
        return ~jnp.any(m.wall_valid & (hits <= 1.0), axis=1)

    count = humans.x.shape[0]
    if not uses_broad_phase(m):
        return view(jnp.arange(count))

    def update(index: Array, seen: Array) -> Array:
        rows = jnp.minimum(index, count - 1)
        return seen.at[index].set(view(rows), mode="drop")

    return update_flagged_rows(asks, chunk_size(count), update, jnp.ones(count, bool))


def human_forces(
    config: HumanConfig, hp: HumanParams, m: MapArrays, humans: HumanState,
    robot_x: Array, robot_y: Array, robot_vx: Array, robot_vy: Array, robot_in_world: Array,
    robot_moving: Array, robot_radius: Array, dt: Array,
) -> tuple[Array, Array, Array, Array, Array]:
    """Total force per unit mass ``(fx, fy)`` ``[H]`` (m/s^2) on every pedestrian over a
    sub-step of ``dt`` s, its heading (rad) and turn rate (rad/s) after it, and the bodies left
    out of a full cell list (int32 scalar; 0 without cell lists): the driving term, the
    interaction with the other pedestrians and the robots (``[R]`` arrays: position,
    velocity, in the world, moving (parked robots are static), radius (m); the force laws count
    robots ``robot_weight``) within ``config.neighbor_range``, and walls. ORCA's force is the
    change to its velocity over ``dt``; HSFM turns its heading under a torque; the other models
    face the way they walk."""
    find = config.each(m)
    if config.force_model == "orca":
        fx, fy, overflow = orca_forces(hp, m, humans, robot_x, robot_y, robot_vx, robot_vy,
                                       robot_in_world, robot_moving, robot_radius, dt,
                                       config.orca_neighbors, config.orca_walls, find,
                                       config.neighbor_range)
        return (fx, fy, *_facing(humans, fx, fy, dt), overflow)
    if config.force_model == "hsfm":
        return hsfm_update(hp, m, humans, robot_x, robot_y, robot_vx, robot_vy, robot_in_world,
                           robot_radius, dt, find, config.neighbor_range)
    fx, fy, overflow = _social_forces(config, hp, m, humans, robot_x, robot_y, robot_vx,
                                      robot_vy, robot_in_world, find)
    return (fx, fy, *_facing(humans, fx, fy, dt), overflow)


def _facing(humans: HumanState, fx: Array, fy: Array, dt: Array) -> tuple[Array, Array]:
    """Heading (rad) and turn rate (rad/s) of pedestrians that face the way they walk: the
    direction of the new velocity ``v + dt F`` once faster than 5 cm/s, else unchanged."""
    vx, vy = humans.vx + dt * fx, humans.vy + dt * fy
    moving = humans.active & (vx * vx + vy * vy > 0.0025)
    heading = jnp.where(moving, polynomial_atan2(vy, vx), humans.heading)
    return heading, wrap_angle(heading - humans.heading) / dt


def _social_forces(
    config: HumanConfig, hp: HumanParams, m: MapArrays, humans: HumanState,
    robot_x: Array, robot_y: Array, robot_vx: Array, robot_vy: Array, robot_in_world: Array,
    find: Each,
) -> tuple[Array, Array, Array]:
    """``(fx, fy)`` ``[H]`` (m/s^2) of the Moussaid or Helbing-Molnar laws, and the cell
    lists' overflow (``find``: how the pedestrians meet the bodies, :meth:`HumanConfig.each`)."""
    p = hp.forces
    h = humans
    tx, ty = walking_target(m, h)
    fx, fy = desired_force(h.x, h.y, h.vx, h.vy, tx, ty, h.desired_speed, p.tau)
    bx, by = jnp.concatenate([h.x, robot_x]), jnp.concatenate([h.y, robot_y])
    bvx, bvy = jnp.concatenate([h.vx, robot_vx]), jnp.concatenate([h.vy, robot_vy])
    # 0/1 factors rather than selects (they fuse into the pair kernel; see forces.py).
    robots = robot_in_world.astype(jnp.float32) * hp.robot_weight
    ex, ey, _ = unit(tx - h.x, ty - h.y)

    def interact(pairs: Pairs, x: Array, y: Array, vx: Array, vy: Array, hx: Array,
                 hy: Array) -> tuple[Array, Array]:
        others = (pairs.gather(bx), pairs.gather(by), pairs.gather(bvx, 0.0),
                  pairs.gather(bvy, 0.0))
        if config.force_model == "moussaid":
            return moussaid_interaction(x, y, vx, vy, *others, pairs.weight, p)
        return helbing_interaction(x, y, hx, hy, *others, pairs.weight, p)

    (sx, sy), overflow = find(interact, bx, by,
                              jnp.concatenate([h.active.astype(jnp.float32), robots]),
                              h.vx, h.vy, ex, ey)
    if config.force_model == "moussaid":
        if config.wall_model == "points":
            away_x = h.x[:, None] - hp.wall_points_x[None, :]
            away_y = h.y[:, None] - hp.wall_points_y[None, :]
            valid = jnp.ones(hp.wall_points_x.shape, bool)
            if config.neighbor_range is not None:  # wall points beyond the range do not act
                reach = config.neighbor_range
                valid = valid & (away_x * away_x + away_y * away_y < reach * reach)
        else:
            away_x, away_y, valid, _ = wall_offsets(h.x, h.y, m, config.neighbor_range)
        wx, wy = exponential_wall_force(away_x, away_y, valid,
                                        jnp.broadcast_to(hp.radius, h.x.shape), p)
    else:
        away_x, away_y, valid, _ = wall_offsets(h.x, h.y, m, config.neighbor_range)
        wx, wy = helbing_wall_force(away_x, away_y, valid, p)
    if hp.groups is not None:
        gx, gy = group_forces(hp.groups, h.x, h.y, h.vx, h.vy, tx, ty, h.active)
        wx, wy = wx + gx, wy + gy
    return fx + sx + wx, fy + sy + wy, overflow


def move_humans(
    hp: HumanParams, m: MapArrays, humans: HumanState, fx: Array, fy: Array, dt: Array
) -> HumanState:
    """Semi-implicit Euler (as PySocialForce): ``v <- cap(v + dt F)``, ``x <- x + dt v``, with
    the move cut at the first wall contact (swept test, so no step size tunnels through a wall);
    a pedestrian stopped by a wall keeps only the allowed part of its velocity."""
    h = humans
    vx, vy = cap_speed(h.vx + dt * fx, h.vy + dt * fy, hp.max_speed_factor * h.desired_speed)
    vx, vy = jnp.where(h.active, vx, 0.0), jnp.where(h.active, vy, 0.0)
    dx, dy = vx * dt, vy * dt
    radius = jnp.broadcast_to(hp.radius, h.x.shape)
    allowed_x, allowed_y, hit = clamp_to_walls(h.x, h.y, dx, dy, radius, m)
    vx = jnp.where(hit, allowed_x / dt, vx)
    vy = jnp.where(hit, allowed_y / dt, vy)
    return h.replace(x=h.x + allowed_x, y=h.y + allowed_y, vx=vx, vy=vy)


def yield_to_robots(
    hp: HumanParams, m: MapArrays, humans: HumanState,
    robot_x: Array, robot_y: Array, robot_radius: Array, robot_in_world: Array,
) -> tuple[HumanState, Array]:
    """Push pedestrians out of robot bodies (pedestrians give way; a robot is not moved), cut at
    walls. Returns the pedestrians and ``[R]`` flags: robot overlapped a pedestrian."""
    h = humans
    rx = h.x[:, None] - robot_x[None, :]
    ry = h.y[:, None] - robot_y[None, :]
    ux, uy, dist = unit(rx, ry)
    ux = jnp.where(dist > 0.0, ux, 1.0)  # coincident centres: push along +x
    pair = h.active[:, None] & robot_in_world[None, :]
    overlap = jnp.where(pair, hp.radius + robot_radius[None, :] - dist, 0.0)
    touching = overlap > 0.0
    push = jnp.where(touching, overlap, 0.0)
    px, py = jnp.sum(push * ux, axis=1), jnp.sum(push * uy, axis=1)
    radius = jnp.broadcast_to(hp.radius, h.x.shape)
    px, py, _ = clamp_to_walls(h.x, h.y, px, py, radius, m)
    return h.replace(x=h.x + px, y=h.y + py), jnp.any(touching, axis=0)
