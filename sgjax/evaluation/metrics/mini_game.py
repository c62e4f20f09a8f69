"""Multi-robot mini-game metrics: turns taken at conflict zones (order violations), makespan
and flow rate through the zones.

Order violations and the flow rate need the zone books: build the environment with
``EnvConfig.track_zones`` (the evaluation runner does), else they read NaN.
"""

from __future__ import annotations

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.evaluation.metrics.base import (
    Metric,
    episode_metric,
    known,
    robot_metric,
    team_success,
)
from sgjax.evaluation.metrics.constants import MetricConstants
from sgjax.evaluation.metrics.registration import register_metric
from sgjax.evaluation.metrics.step_view import EpisodeEnd, StepView
from sgjax.kernels import zone_books as zn
from sgjax.types import EnvParams, EnvState


@struct.dataclass
class MiniGameTally:
    """Per robot ``[R]`` int32, per zone ``[Z]`` int32, or scalars."""

    all_done_at: Array  # int32 scalar: step when every robot had arrived (0: not yet)
    bad_entries: Array  # [R]: zone entries out of turn
    bad_exits: Array  # [R]: zone exits out of turn
    zone_exits: Array  # [Z]: robots that left each conflict zone
    zone_first_entry: Array  # [Z]: step of the first entry (-1: none)
    zone_last_exit: Array  # [Z]: step of the last exit (-1: none)


def zone_traffic(prev: EnvState, state: EnvState) -> tuple[Array, Array]:
    """Robots that entered and that left each tracked conflict zone this step, ``[Z]`` int32
    (a robot that crossed a zone within one step counts as both)."""
    before, after = prev.zones.phase, state.zones.phase
    entered = (before == zn.BEFORE) & (after != zn.BEFORE)
    exited = (before != zn.LEFT) & (after == zn.LEFT)
    return (jnp.sum(entered, axis=0).astype(jnp.int32),
            jnp.sum(exited, axis=0).astype(jnp.int32))


def order_violations(prev: EnvState, state: EnvState, params: EnvParams
                     ) -> tuple[Array, Array]:
    """Zone entries and exits out of turn this step, per robot ``[R]`` int32 (zeros without
    zone books). In turn: the robot's queue place equals its priority, both read before the
    step (as the ``zone_order`` reward reads them)."""
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


@register_metric
class MiniGame(Metric):
    """What the team does at a bottleneck: who goes out of turn, when the last robot arrives,
    and how many robots pass a zone per metre of its free width and second."""

    infos = (
        robot_metric("order_violations_entry", "count",
                     "entries into a conflict zone while the robot's place in the queue differs "
                     "from its assigned priority, summed (NaN on maps without zones)",
                     "SocialGym 2.0 incorrect_enter_rate", reduce="sum"),
        robot_metric("order_violations_exit", "count",
                     "exits from a conflict zone out of turn, summed (NaN without zones)",
                     "SocialGym 2.0 incorrect_exit_rate", reduce="sum"),
        episode_metric("aggregated_time", "s",
                       "dt x steps until every robot arrived, team successes only (NaN "
                       "otherwise)", "Francis et al. 2023 (AT)"),
        episode_metric("makespan", "s",
                       "dt x steps until the last robot arrived, team successes only (NaN "
                       "otherwise); the same number as aggregated_time, under the multi-agent "
                       "planning name", "SMGLib (Chandra et al.); Stern et al. 2019"),
        episode_metric("flow_rate", "1/(m s)",
                       "robots through a conflict zone per metre of its free width per second: "
                       "exits / (zone_width x (last exit - first entry) x dt), averaged over the "
                       "map's zones with an exit after an earlier entry (NaN otherwise); "
                       "zone_width is the gap between the obstacles inside the zone (1 m door, "
                       "1 m corridor, 4 m roads; maps.arrays.zone_widths)",
                       "SMGLib flow rate, per metre and second"),
    )

    def start(self, num_robots: int, num_zones: int, constants: MetricConstants
              ) -> MiniGameTally:
        zi, none = jnp.zeros(num_robots, jnp.int32), jnp.full(num_zones, -1, jnp.int32)
        return MiniGameTally(all_done_at=jnp.zeros((), jnp.int32), bad_entries=zi,
                             bad_exits=zi, zone_exits=jnp.zeros(num_zones, jnp.int32),
                             zone_first_entry=none, zone_last_exit=none)

    def update(self, tally: MiniGameTally, view: StepView) -> MiniGameTally:
        prev, state, running = view.prev, view.state, view.running
        robots = state.robots
        bad_entries, bad_exits = order_violations(prev, state, view.params)
        entries, exits = zone_traffic(prev, state)
        now = state.time
        all_arrived = jnp.all(~robots.present | robots.succeeded) & jnp.any(robots.present)
        return MiniGameTally(
            all_done_at=jnp.where(running & all_arrived & (tally.all_done_at == 0), now,
                                  tally.all_done_at),
            bad_entries=view.add(tally.bad_entries, bad_entries),  # robots that moved as learners
            bad_exits=view.add(tally.bad_exits, bad_exits),
            zone_exits=tally.zone_exits + jnp.where(running, exits, 0),
            zone_first_entry=jnp.where(running & (entries > 0) & (tally.zone_first_entry < 0),
                                       now, tally.zone_first_entry),
            zone_last_exit=jnp.where(running & (exits > 0), now, tally.zone_last_exit),
        )

    def finalize(self, tally: MiniGameTally, end: EpisodeEnd) -> dict[str, Array]:
        dt = end.dt
        team = team_success(end.present, end.robots.succeeded)
        makespan = known(tally.all_done_at * dt, team)  # s until the last robot arrived
        span = (tally.zone_last_exit - tally.zone_first_entry).astype(jnp.float32) * dt
        flowing = (tally.zone_exits > 0) & (tally.zone_first_entry >= 0) & (span > 0.0)
        widths = end.params.map.zone_width[:tally.zone_exits.shape[0]]
        flow = tally.zone_exits / (jnp.maximum(widths, 1e-6) * jnp.where(flowing, span, 1.0))
        flow_rate = known(jnp.sum(jnp.where(flowing, flow, 0.0))
                          / jnp.maximum(jnp.sum(flowing), 1), jnp.any(flowing))
        return {
            "order_violations_entry": known(tally.bad_entries, end.has_zones),
            "order_violations_exit": known(tally.bad_exits, end.has_zones),
            "aggregated_time": makespan,
            "makespan": makespan,
            "flow_rate": flow_rate,
        }
