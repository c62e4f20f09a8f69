"""Social-navigation metrics, accumulated inside the jitted step (no host-side trajectories).

One :class:`MetricState` per environment is carried beside the ``EnvState``::

    m = metrics.start(env.max_agents)
    obs, next_state, reward, term, trunc, info = env.step_env(key, state, actions, params)
    done = metrics.episode_done(next_state, term, trunc)
    m = metrics.update(m, state, next_state, info, done, params, env.config)
    ...
    robot, episode = metrics.finalize(m, final_state, params)

``finalize`` gives per-robot values ``[R]`` (NaN for robots not in the episode) and per-episode
scalars; :func:`per_episode` reduces both to one number per metric and episode, the unit the
evaluation runner averages and puts confidence intervals on. Every metric's definition,
constants and source are in :data:`METRICS`, :class:`MetricConstants` and ``docs/metrics.md``.
``sgjax.evaluation.evaluate`` runs whole batches of episodes with this module.

Zone-order violations need the zone books: build the environment with
``EnvConfig.track_zones`` (``sgjax.evaluation.evaluate`` does), else they read NaN.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.kernels import zone_books as zn
from sgjax.kernels.geometry import safe_norm, wrap_angle

if TYPE_CHECKING:
    from sgjax.environment.env import EnvConfig
    from sgjax.types import EnvParams, EnvState


@dataclasses.dataclass(frozen=True)
class MetricConstants:
    """The thresholds the metrics use (recorded in every evaluation output)."""

    stop_speed: float = 0.01  # m/s: "stopped" below this speed ...
    stop_turn_rate: float = 0.02  # rad/s: ... and this turn rate (HuNavSim)
    freeze_time: float = 1.0  # s: a stop this long while on the way is a freezing event
    deadlock_time: float = 5.0  # s: every unfinished robot (two or more) stopped this long
    space_radii: tuple[float, float, float] = (0.45, 1.2, 3.6)  # m: intimate, personal, social
    ttc_threshold: float = 2.0  # s: fraction of steps with time-to-collision below this
    ttc_cap: float = 10.0  # s: time-to-collision is capped here (no approach = the cap)

    def as_dict(self) -> dict[str, float | list[float]]:
        return {k: list(v) if isinstance(v, tuple) else v
                for k, v in dataclasses.asdict(self).items()}


DEFAULT_CONSTANTS = MetricConstants()
SPACE_NAMES = ("intimate", "personal", "social")


@dataclasses.dataclass(frozen=True)
class MetricInfo:
    """One metric: ``level`` says whether it is measured per robot (then reduced over an
    episode's robots by ``reduce``, "mean" or "sum") or per episode; ``binary`` metrics get a
    Wilson interval, the others a Student-t interval over episodes."""

    name: str
    unit: str
    level: str
    reduce: str
    binary: bool
    definition: str
    source: str


def _m(name: str, unit: str, level: str, reduce: str, definition: str, source: str,
       binary: bool = False) -> MetricInfo:
    return MetricInfo(name, unit, level, reduce, binary, definition, source)


# Metrics that compare an episode with the same episode played again with a robot alone or
# without it (sgjax.evaluation.counterfactual; NaN unless the evaluation runs those lanes).
COUNTERFACTUAL_METRICS: tuple[MetricInfo, ...] = (
    _m("makespan_ratio", "ratio", "episode", "mean",
       "makespan / the slowest robot's arrival time when it plays the same episode alone "
       "(team successes whose robots all arrive alone; NaN otherwise)", "SMGLib"),
    _m("path_deviation_mean", "m", "robot", "mean",
       "mean over the robot's active steps of the distance from its position to its own path "
       "in the same episode alone (polyline of its positions there)",
       "SMGLib path deviation, with the exact solo path for the straight line"),
    _m("path_deviation_max", "m", "robot", "mean", "max of the same", "SMGLib"),
    _m("hausdorff", "m", "robot", "mean",
       "Hausdorff distance between the robot's path and its own path alone (both polylines, "
       "start to where it stopped)", "SMGLib Hausdorff distance"),
    _m("invasiveness_robots", "m", "robot", "mean",
       "mean over steps (while this episode or the one without the robot runs) and over the "
       "other robots of the distance between where they are with and without this robot",
       "SMGLib's reverted invasiveness, made exact by a counterfactual lane"),
    _m("invasiveness_humans", "m", "robot", "mean",
       "the same over the pedestrians (NaN without any)", "sgjax"),
    _m("invasiveness_speed", "m/s", "robot", "mean",
       "the same for speeds: mean over steps and over the other robots and pedestrians of "
       "|speed with - speed without this robot|", "sgjax"),
)
COUNTERFACTUAL_NAMES = tuple(m.name for m in COUNTERFACTUAL_METRICS)

METRICS: tuple[MetricInfo, ...] = (
    _m("success", "fraction", "robot", "mean",
       "robot reached its goal (centre within goal_tolerance) before the episode ended; the "
       "episode value is the fraction of its robots (partial success)",
       "SocialGym 2.0 `succeeded`; socialnav.md C1"),
    _m("team_success", "fraction", "episode", "mean",
       "every robot of the episode reached its goal", "SocialGym 2.0 success_rate", binary=True),
    _m("clean_success", "fraction", "robot", "mean",
       "reached the goal with no collision onset of any kind", "socialnav.md C1 (Success)"),
    _m("timeout", "fraction", "robot", "mean",
       "robot neither arrived nor was ended by an ender when the episode ended (time limit or "
       "stuck truncation)", "socialnav.md C1"),
    _m("collision_ended", "fraction", "robot", "mean",
       "robot was ended by the collision ender (0 unless that ender is configured)", "sgjax"),
    _m("collisions", "count", "robot", "sum",
       "collision onsets (steps a contact starts) of any kind, summed over the episode's "
       "robots: the paper's Coll. Rate", "SocialGym 2.0 `collisions` (rising edges)"),
    _m("collisions_robot", "count", "robot", "sum", "robot-robot collision onsets, summed",
       "SocialGym 2.0"),
    _m("collisions_human", "count", "robot", "sum", "robot-pedestrian collision onsets, summed",
       "socialnav.md C1"),
    _m("collisions_wall", "count", "robot", "sum", "robot-wall collision onsets, summed",
       "socialnav.md C1"),
    _m("collision_episode", "fraction", "episode", "mean",
       "the episode had at least one collision onset", "socialnav.md C1 (Collision rate)",
       binary=True),
    _m("time_to_goal", "s", "robot", "mean",
       "arrival step x dt, successful robots only (NaN without one)", "CrowdNav, socialnav.md C1"),
    _m("path_length", "m", "robot", "mean", "sum of the distances moved per step while active",
       "socialnav.md C1"),
    _m("spl", "fraction", "robot", "mean",
       "success x L / max(L, path_length), L the length of the shortest route on the map's "
       "navigation graph from start to goal", "Anderson et al. 2018; socialnav.md C1"),
    _m("path_irregularity", "rad", "robot", "mean",
       "total rotation: sum over active steps of |wrap(heading change)|", "HuNavSim CHC, SEAN"),
    _m("path_irregularity_per_m", "rad/m", "robot", "mean",
       "path_irregularity / path_length (NaN below 1 mm)", "SocNavBench"),
    _m("stop_time", "s", "robot", "mean",
       "dt x steps on the way (not finished) with speed < stop_speed and |turn rate| < "
       "stop_turn_rate", "HuNavSim time_not_moving; the paper's Stop Time"),
    _m("freezes", "count", "robot", "sum",
       "stops lasting freeze_time or longer while on the way, summed over robots",
       "socialnav.md C1 (freezing)"),
    _m("velocity_change_sum", "m/s", "robot", "mean",
       "sum over active steps of |v(t+1) - v(t)| (world velocity vectors)",
       "socialnav.md C1; SocialGym 2.0 avg_velocity_delta used scalar speeds"),
    _m("velocity_change_max", "m/s", "robot", "mean",
       "max over active steps of |v(t+1) - v(t)|: the paper's Max delta-V",
       "SocialGym 2.0 paper Table 3"),
    _m("turn_rate_change_sum", "rad/s", "robot", "mean",
       "sum over active steps of |omega(t+1) - omega(t)|", "socialnav.md C1"),
    _m("acceleration_mean", "m/s^2", "robot", "mean",
       "mean over active steps of |v(t+1) - v(t)| / dt", "SocNavGym, social-jym"),
    _m("acceleration_max", "m/s^2", "robot", "mean", "max of the same", "SocNavGym"),
    _m("jerk_mean", "m/s^3", "robot", "mean",
       "mean over consecutive active steps of |a(t+1) - a(t)| / dt", "SocNavGym, SEAN"),
    _m("jerk_max", "m/s^3", "robot", "mean", "max of the same", "SocNavGym"),
    _m("min_distance_human", "m", "robot", "mean",
       "min over active steps and pedestrians of centre distance - both radii (NaN without "
       "pedestrians)", "HuNavSim, socialnav.md C1"),
    _m("min_distance_robot", "m", "robot", "mean",
       "min over active steps and other robots in the world (active, settling or parked) of "
       "centre distance - both radii",
       "socialnav.md C1"),
    *(_m(f"{space}_space_{kind}", "fraction", "robot", "mean",
         f"fraction of active steps with the nearest {kind} body gap < {radius} m "
         f"(space_radii[{k}]; NaN without any {kind} body)", "HuNavSim, SEAN")
      for kind in ("human", "robot")
      for k, (space, radius) in enumerate(
          zip(SPACE_NAMES, DEFAULT_CONSTANTS.space_radii, strict=True))),
    _m("min_ttc", "s", "robot", "mean",
       "min over active steps of the time-to-collision with any other body at constant "
       "velocities (smallest tau >= 0 with |dp + tau dv| = r_i + r_j; 0 when touching), "
       "capped at ttc_cap", "socialnav.md C1"),
    _m("ttc_below_threshold", "fraction", "robot", "mean",
       "fraction of active steps with time-to-collision < ttc_threshold", "socialnav.md C1"),
    _m("order_violations_entry", "count", "robot", "sum",
       "entries into a conflict zone while the robot's place in the queue differs from its "
       "assigned priority, summed (NaN on maps without zones)",
       "SocialGym 2.0 incorrect_enter_rate"),
    _m("order_violations_exit", "count", "robot", "sum",
       "exits from a conflict zone out of turn, summed (NaN without zones)",
       "SocialGym 2.0 incorrect_exit_rate"),
    _m("episode_length", "steps", "episode", "mean",
       "steps until every robot finished or the episode was truncated: the paper's Avg. Length",
       "SocialGym 2.0 avg_length"),
    _m("aggregated_time", "s", "episode", "mean",
       "dt x steps until every robot arrived, team successes only (NaN otherwise)",
       "Francis et al. 2023 (AT)"),
    _m("deadlock", "fraction", "episode", "mean",
       "two or more unfinished robots, all stopped, for deadlock_time or longer",
       "socialnav.md C1 (multi-robot)", binary=True),
    _m("stuck_end", "fraction", "episode", "mean",
       "the episode was truncated before the time limit (stuck ender)", "SocialGym 2.0",
       binary=True),
    _m("makespan", "s", "episode", "mean",
       "dt x steps until the last robot arrived, team successes only (NaN otherwise); the "
       "same number as aggregated_time, under the multi-agent planning name",
       "SMGLib (Chandra et al.); Stern et al. 2019"),
    _m("flow_rate", "1/(m s)", "episode", "mean",
       "robots through a conflict zone per metre of its free width per second: exits / "
       "(zone_width x (last exit - first entry) x dt), averaged over the map's zones with an "
       "exit after an earlier entry (NaN otherwise); zone_width is the gap between the "
       "obstacles inside the zone (1 m door, 1 m corridor, 4 m roads; maps.arrays.zone_widths)",
       "SMGLib flow rate, per metre and second"),
    *COUNTERFACTUAL_METRICS,
)
METRIC_NAMES = tuple(m.name for m in METRICS)
METRICS_BY_NAME = {m.name: m for m in METRICS}


@struct.dataclass
class MetricState:
    """Per-step accumulators of one environment; ``[R]`` unless noted."""

    running: Array  # bool scalar: the episode has not ended
    length: Array  # int32 scalar: steps the episode ran
    all_done_at: Array  # int32 scalar: step when every robot had arrived (0: not yet)
    arrived_at: Array  # int32: arrival step (0: not arrived)
    steps: Array  # int32: active steps
    path_length: Array  # m
    turning: Array  # rad
    stop_steps: Array  # int32
    stopped_run: Array  # int32: consecutive stopped steps so far
    freezes: Array  # int32
    dv_sum: Array  # m/s
    dv_max: Array  # m/s
    domega_sum: Array  # rad/s
    accel_sum: Array  # m/s^2
    accel_max: Array
    jerk_sum: Array  # m/s^3
    jerk_max: Array
    jerk_steps: Array  # int32
    last_accel: Array  # [R, 2] m/s^2
    has_accel: Array  # bool
    min_gap_robot: Array  # m (inf: never another robot)
    min_gap_human: Array  # m (inf: never a pedestrian)
    near_robot: Array  # [3, R] int32: steps inside each space radius
    near_human: Array  # [3, R] int32
    min_ttc: Array  # s
    ttc_low: Array  # int32
    stall_run: Array  # int32 scalar: consecutive all-stopped steps
    deadlock: Array  # bool scalar
    bad_entries: Array  # int32
    bad_exits: Array  # int32
    zone_exits: Array  # [Z] int32: robots that left each conflict zone
    zone_first_entry: Array  # [Z] int32: step of the first entry (-1: none)
    zone_last_exit: Array  # [Z] int32: step of the last exit (-1: none)


def start(num_robots: int, constants: MetricConstants = DEFAULT_CONSTANTS, num_zones: int = 0
          ) -> MetricState:
    """Empty accumulators for a fresh episode of ``num_robots`` robot slots and ``num_zones``
    tracked conflict zones (``state.zones.phase.shape[1]``; 0 without zone books)."""
    r, k = num_robots, len(constants.space_radii)
    none = jnp.full(num_zones, -1, jnp.int32)
    zf, zi = jnp.zeros(r, jnp.float32), jnp.zeros(r, jnp.int32)
    inf = jnp.full(r, jnp.inf, jnp.float32)
    return MetricState(
        running=jnp.ones((), bool), length=jnp.zeros((), jnp.int32),
        all_done_at=jnp.zeros((), jnp.int32), arrived_at=zi, steps=zi, path_length=zf,
        turning=zf, stop_steps=zi, stopped_run=zi, freezes=zi, dv_sum=zf, dv_max=zf,
        domega_sum=zf, accel_sum=zf, accel_max=zf, jerk_sum=zf, jerk_max=zf, jerk_steps=zi,
        last_accel=jnp.zeros((r, 2), jnp.float32), has_accel=jnp.zeros(r, bool),
        min_gap_robot=inf, min_gap_human=inf, near_robot=jnp.zeros((k, r), jnp.int32),
        near_human=jnp.zeros((k, r), jnp.int32), min_ttc=jnp.full(r, constants.ttc_cap),
        ttc_low=zi, stall_run=jnp.zeros((), jnp.int32), deadlock=jnp.zeros((), bool),
        bad_entries=zi, bad_exits=zi, zone_exits=jnp.zeros(num_zones, jnp.int32),
        zone_first_entry=none, zone_last_exit=none,
    )


def episode_done(state: EnvState, terminated: Array, truncated: Array) -> Array:
    """Whether every robot of the episode is done after a step (bool scalar)."""
    return jnp.all(~state.robots.present | terminated | truncated)


def _gaps(x: Array, y: Array, radius: Array, ox: Array, oy: Array, oradius: Array,
          others: Array) -> Array:
    """Body gaps (m) ``[R, N]`` from robots to other bodies; inf where ``others [R, N]`` is
    False."""
    gap = safe_norm(ox[None, :] - x[:, None], oy[None, :] - y[:, None])
    gap = gap - radius[:, None] - oradius[None, :]
    return jnp.where(others, gap, jnp.inf)


def time_to_collision(dpx: Array, dpy: Array, dvx: Array, dvy: Array, reach: Array) -> Array:
    """Smallest ``tau >= 0`` with ``|dp + tau dv| = reach`` (s); 0 when already within
    ``reach``, inf when the bodies never get that close. Element-wise."""
    a = dvx * dvx + dvy * dvy
    b = 2.0 * (dpx * dvx + dpy * dvy)
    c = dpx * dpx + dpy * dpy - reach * reach
    disc = b * b - 4.0 * a * c
    closing = (b < 0.0) & (disc >= 0.0) & (a > 1e-12)
    root = (-b - jnp.sqrt(jnp.maximum(disc, 0.0))) / (2.0 * jnp.where(closing, a, 1.0))
    return jnp.where(c <= 0.0, 0.0, jnp.where(closing, root, jnp.inf))


def update(
    m: MetricState, prev: EnvState, state: EnvState, info: dict, done: Array,
    params: EnvParams, config: EnvConfig, constants: MetricConstants = DEFAULT_CONSTANTS,
) -> MetricState:
    """Accumulate one step ``prev -> state`` (``info`` from ``env.step_env``; ``done`` from
    :func:`episode_done`). Steps after the episode ended change nothing."""
    running = m.running
    was_active = info["was_active"] & running  # active before the step
    still_active = state.robots.active & running  # still unfinished after it
    dt = params.dt
    robots0, robots1 = prev.robots, state.robots
    v0, v1 = robots0.velocity, robots1.velocity

    moved = safe_norm(robots1.x - robots0.x, robots1.y - robots0.y)
    turned = jnp.abs(wrap_angle(robots1.heading - robots0.heading))
    slow = ((safe_norm(v1[:, 0], v1[:, 1]) < constants.stop_speed)
            & (jnp.abs(robots1.kin.omega) < constants.stop_turn_rate))
    stopped = still_active & slow
    stopped_run = jnp.where(stopped, m.stopped_run + 1, 0)
    freeze_steps = jnp.maximum(jnp.ceil(constants.freeze_time / dt - 1e-6), 1).astype(jnp.int32)

    dv = v1 - v0
    dv_norm = safe_norm(dv[:, 0], dv[:, 1])
    accel = dv / dt
    jerk_vec = (accel - m.last_accel) / dt
    jerk = safe_norm(jerk_vec[:, 0], jerk_vec[:, 1])
    jerk_ok = was_active & m.has_accel

    # Gaps to the other robots that were in the world during the step, and to pedestrians.
    radius = params.robots.radius
    x, y = robots1.x, robots1.y
    num_robots = x.shape[0]
    other_robot = prev.robots.in_world[None, :] & ~jnp.eye(num_robots, dtype=bool)
    gap_robot = _gaps(x, y, radius, x, y, radius, other_robot)
    humans = state.humans
    human_radius = jnp.broadcast_to(params.humans.radius, humans.x.shape)
    gap_human = _gaps(x, y, radius, humans.x, humans.y, human_radius,
                      jnp.broadcast_to(humans.active[None, :], (num_robots, humans.x.shape[0])))
    nearest_robot = jnp.min(gap_robot, axis=1, initial=jnp.inf)
    nearest_human = jnp.min(gap_human, axis=1, initial=jnp.inf)
    radii = jnp.asarray(constants.space_radii, jnp.float32)[:, None]

    # Time to collision with every other body at constant velocity.
    ox = jnp.concatenate([x, humans.x])
    oy = jnp.concatenate([y, humans.y])
    body_v = robots1.body_velocity  # parked robots are at rest
    ovx = jnp.concatenate([body_v[:, 0], humans.vx])
    ovy = jnp.concatenate([body_v[:, 1], humans.vy])
    oradius = jnp.concatenate([radius, human_radius])
    ttc = time_to_collision(ox[None, :] - x[:, None], oy[None, :] - y[:, None],
                            ovx[None, :] - v1[:, 0:1], ovy[None, :] - v1[:, 1:2],
                            oradius[None, :] + radius[:, None])
    others = jnp.concatenate([other_robot, gap_human < jnp.inf], axis=1)
    ttc = jnp.min(jnp.where(others, ttc, jnp.inf), axis=1, initial=jnp.inf)
    ttc = jnp.minimum(ttc, constants.ttc_cap)

    # Deadlock: two or more unfinished robots, all stopped.
    stalled = (jnp.sum(still_active) >= 2) & jnp.all(stopped | ~still_active)
    stall_run = jnp.where(stalled, m.stall_run + 1, 0)
    deadlock_steps = jnp.maximum(jnp.ceil(constants.deadlock_time / dt - 1e-6), 1)

    bad_entries, bad_exits = _order_violations(prev, state, params, config)
    entries, exits = _zone_traffic(prev, state)
    now = state.time

    arrived = info["arrived"] & running
    all_arrived = jnp.all(~robots1.present | robots1.succeeded) & jnp.any(robots1.present)

    def add(total: Array, value: Array, mask: Array = was_active) -> Array:
        return total + jnp.where(mask, value, 0).astype(total.dtype)

    def most(best: Array, value: Array, mask: Array = was_active) -> Array:
        return jnp.where(mask, jnp.maximum(best, value), best)

    def least(best: Array, value: Array) -> Array:
        return jnp.where(was_active, jnp.minimum(best, value), best)

    return MetricState(
        running=running & ~done,
        length=jnp.where(running, state.time, m.length),
        all_done_at=jnp.where(running & all_arrived & (m.all_done_at == 0), state.time,
                              m.all_done_at),
        arrived_at=jnp.where(arrived, state.time, m.arrived_at),
        steps=add(m.steps, 1),
        path_length=add(m.path_length, moved),
        turning=add(m.turning, turned),
        stop_steps=add(m.stop_steps, 1, stopped),
        stopped_run=stopped_run,
        freezes=add(m.freezes, 1, stopped & (stopped_run == freeze_steps)),
        dv_sum=add(m.dv_sum, dv_norm),
        dv_max=most(m.dv_max, dv_norm),
        domega_sum=add(m.domega_sum, jnp.abs(robots1.kin.omega - robots0.kin.omega)),
        accel_sum=add(m.accel_sum, dv_norm / dt),
        accel_max=most(m.accel_max, dv_norm / dt),
        jerk_sum=add(m.jerk_sum, jerk, jerk_ok),
        jerk_max=most(m.jerk_max, jerk, jerk_ok),
        jerk_steps=add(m.jerk_steps, 1, jerk_ok),
        last_accel=jnp.where(was_active[:, None], accel, m.last_accel),
        has_accel=m.has_accel | was_active,
        min_gap_robot=least(m.min_gap_robot, nearest_robot),
        min_gap_human=least(m.min_gap_human, nearest_human),
        near_robot=m.near_robot + (was_active & (nearest_robot < radii)).astype(jnp.int32),
        near_human=m.near_human + (was_active & (nearest_human < radii)).astype(jnp.int32),
        min_ttc=least(m.min_ttc, ttc),
        ttc_low=add(m.ttc_low, 1, was_active & (ttc < constants.ttc_threshold)),
        stall_run=jnp.where(running, stall_run, m.stall_run),
        deadlock=m.deadlock | (running & (stall_run >= deadlock_steps)),
        bad_entries=add(m.bad_entries, bad_entries),  # robots that moved as learners
        bad_exits=add(m.bad_exits, bad_exits),
        zone_exits=m.zone_exits + jnp.where(running, exits, 0),
        zone_first_entry=jnp.where(running & (entries > 0) & (m.zone_first_entry < 0), now,
                                   m.zone_first_entry),
        zone_last_exit=jnp.where(running & (exits > 0), now, m.zone_last_exit),
    )


def _zone_traffic(prev: EnvState, state: EnvState) -> tuple[Array, Array]:
    """Robots that entered and that left each tracked conflict zone this step, ``[Z]`` int32
    (a robot that crossed a zone within one step counts as both)."""
    before, after = prev.zones.phase, state.zones.phase
    entered = (before == zn.BEFORE) & (after != zn.BEFORE)
    exited = (before != zn.LEFT) & (after == zn.LEFT)
    return (jnp.sum(entered, axis=0).astype(jnp.int32),
            jnp.sum(exited, axis=0).astype(jnp.int32))


def _order_violations(prev: EnvState, state: EnvState, params: EnvParams, config: EnvConfig
                      ) -> tuple[Array, Array]:
    """Zone entries and exits out of turn this step, per robot ``[R]`` (zeros without zone
    books). In turn: the robot's queue place equals its priority, both read before the step
    (as the ``zone_order`` reward reads them)."""
    before, after = prev.zones, state.zones
    if before.phase.shape[1] == 0:
        zero = jnp.zeros(prev.robots.x.shape, jnp.int32)
        return zero, zero
    rect = params.map.zone_rect
    in_turn = zn.priority_rank(before) == zn.current_rank(before, prev.robots.x, prev.robots.y,
                                                          rect)
    entered = (before.phase == zn.BEFORE) & (after.phase == zn.INSIDE)
    exited = (before.phase == zn.INSIDE) & (after.phase == zn.LEFT)
    return (jnp.sum(entered & ~in_turn, axis=1).astype(jnp.int32),
            jnp.sum(exited & ~in_turn, axis=1).astype(jnp.int32))


def finalize(
    m: MetricState, state: EnvState, params: EnvParams,
    constants: MetricConstants = DEFAULT_CONSTANTS,
) -> tuple[dict[str, Array], dict[str, Array]]:
    """Metrics of a finished episode from its accumulators and its final state.

    Returns ``(robot, episode)``: ``{name: [R]}`` for robot-level metrics (NaN for robots not
    in the episode) and ``{name: scalar}`` for episode-level ones (see :data:`METRICS`)."""
    nan = jnp.float32(jnp.nan)
    robots, dt = state.robots, params.dt
    present = robots.present
    success = present & robots.succeeded
    coll = state.collisions
    total = coll.robot + coll.wall + coll.human
    steps = jnp.maximum(m.steps, 1).astype(jnp.float32)
    shortest = state.route.total_length
    has_zones = state.zones.phase.shape[1] > 0

    def known(value: Array, ok: Array) -> Array:
        return jnp.where(ok, value, nan)

    saw_robot = jnp.isfinite(m.min_gap_robot)
    saw_human = jnp.isfinite(m.min_gap_human)
    robot = {
        "success": success,
        "clean_success": success & (total == 0),
        "timeout": present & ~robots.finished,
        "collision_ended": present & robots.ended,
        "collisions": total,
        "collisions_robot": coll.robot,
        "collisions_human": coll.human,
        "collisions_wall": coll.wall,
        "time_to_goal": known(m.arrived_at * dt, success),
        "path_length": m.path_length,
        "spl": success * shortest / jnp.maximum(jnp.maximum(shortest, m.path_length), 1e-6),
        "path_irregularity": m.turning,
        "path_irregularity_per_m": known(m.turning / jnp.maximum(m.path_length, 1e-3),
                                         m.path_length >= 1e-3),
        "stop_time": m.stop_steps * dt,
        "freezes": m.freezes,
        "velocity_change_sum": m.dv_sum,
        "velocity_change_max": m.dv_max,
        "turn_rate_change_sum": m.domega_sum,
        "acceleration_mean": m.accel_sum / steps,
        "acceleration_max": m.accel_max,
        "jerk_mean": known(m.jerk_sum / jnp.maximum(m.jerk_steps, 1), m.jerk_steps > 0),
        "jerk_max": known(m.jerk_max, m.jerk_steps > 0),
        "min_distance_human": known(m.min_gap_human, saw_human),
        "min_distance_robot": known(m.min_gap_robot, saw_robot),
        "min_ttc": m.min_ttc,
        "ttc_below_threshold": m.ttc_low / steps,
        "order_violations_entry": known(m.bad_entries, has_zones),
        "order_violations_exit": known(m.bad_exits, has_zones),
    }
    for k, space in enumerate(SPACE_NAMES):
        robot[f"{space}_space_human"] = known(m.near_human[k] / steps, saw_human)
        robot[f"{space}_space_robot"] = known(m.near_robot[k] / steps, saw_robot)
    robot = {name: jnp.where(present, value.astype(jnp.float32), nan)
             for name, value in robot.items()}
    for info in COUNTERFACTUAL_METRICS:  # filled in by sgjax.evaluation.counterfactual when it runs
        if info.level == "robot":
            robot[info.name] = jnp.full(present.shape, nan)
    team = team_success(present, robots.succeeded)
    makespan = known(m.all_done_at * dt, team)  # s until the last robot arrived (successes)
    span = (m.zone_last_exit - m.zone_first_entry).astype(jnp.float32) * dt
    flowing = (m.zone_exits > 0) & (m.zone_first_entry >= 0) & (span > 0.0)
    widths = params.map.zone_width[:m.zone_exits.shape[0]]
    flow = m.zone_exits / (jnp.maximum(widths, 1e-6) * jnp.where(flowing, span, 1.0))
    flow_rate = known(jnp.sum(jnp.where(flowing, flow, 0.0)) / jnp.maximum(jnp.sum(flowing), 1),
                      jnp.any(flowing))
    episode = {
        "team_success": team,
        "collision_episode": jnp.any(present & (total > 0)),
        "episode_length": m.length,
        "aggregated_time": makespan,
        "deadlock": m.deadlock,
        "stuck_end": (m.length < params.max_steps) & ~jnp.all(~present | robots.finished),
        "makespan": makespan,
        "flow_rate": flow_rate,
        "makespan_ratio": nan,
    }
    return robot, {name: jnp.asarray(v, jnp.float32) for name, v in episode.items()}


def team_success(present: Array, succeeded: Array) -> Array:
    """Team success from ``present`` and ``succeeded`` ``[..., R]``: every robot in the episode
    arrived, and there was one. ``[...]`` bool."""
    return jnp.all(succeeded | ~present, axis=-1) & jnp.any(present, axis=-1)


def per_episode(robot: dict[str, Array], episode: dict[str, Array]) -> dict[str, Array]:
    """One value per metric for an episode, in :data:`METRICS` order: robot-level metrics
    reduced over the robots that have a value (mean or sum; NaN when none has)."""
    values = {}
    for info in METRICS:
        if info.level == "episode":
            values[info.name] = episode[info.name]
            continue
        x = robot[info.name]
        has = jnp.isfinite(x)
        total = jnp.sum(jnp.where(has, x, 0.0), axis=-1)
        count = jnp.sum(has, axis=-1)
        value = total if info.reduce == "sum" else total / jnp.maximum(count, 1)
        values[info.name] = jnp.where(count > 0, value, jnp.nan)
    return values

