"""The counterfactual metrics: an episode compared with the same episode played again with one
robot alone, or without it (the lanes of :mod:`sgjax.evaluation.counterfactual`).

Registered here with the other metric families (:class:`Counterfactual`, ``per_step = False``:
they read NaN unless those lanes run). Definitions (``docs/metrics.md``): path deviation (mean,
max) and Hausdorff distance from the robot's own path alone, the makespan over the slowest
robot's time alone, and invasiveness: how far and how differently fast the other robots and
pedestrians move with versus without the robot. Their accumulator is :class:`Tally`
(:func:`start`, :func:`update`, :func:`finalize`), fed by the lane plan with the robots' solo
paths (:class:`SoloPaths`).
"""

from __future__ import annotations

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.evaluation.metrics.base import Metric, episode_metric, robot_metric
from sgjax.evaluation.metrics.registration import register_metric
from sgjax.kernels.geometry import point_segment_distance_sq, safe_norm
from sgjax.types import EnvParams, EnvState


@register_metric
class Counterfactual(Metric):
    """The metrics that compare an episode with the same episode played again with a robot
    alone or without it. Not computed from the step (``per_step = False``): the runner plays
    the lanes of :func:`play_counterfactual`, whose accumulator is :class:`Tally`
    (:func:`start`, :func:`update`, :func:`finalize`)."""

    per_step = False
    infos = (
        episode_metric("makespan_ratio", "ratio",
                       "makespan / the slowest robot's arrival time when it plays the same "
                       "episode alone (team successes whose robots all arrive alone; NaN "
                       "otherwise)", "SMGLib"),
        robot_metric("path_deviation_mean", "m",
                     "mean over the robot's active steps of the distance from its position to "
                     "its own path in the same episode alone (polyline of its positions there)",
                     "SMGLib path deviation, with the exact solo path for the straight line"),
        robot_metric("path_deviation_max", "m", "max of the same", "SMGLib"),
        robot_metric("hausdorff", "m",
                     "Hausdorff distance between the robot's path and its own path alone (both "
                     "polylines, start to where it stopped)", "SMGLib Hausdorff distance"),
        robot_metric("invasiveness_robots", "m",
                     "mean over steps (while this episode or the one without the robot runs) "
                     "and over the other robots of the distance between where they are with "
                     "and without this robot",
                     "SMGLib's reverted invasiveness, made exact by a counterfactual lane"),
        robot_metric("invasiveness_humans", "m",
                     "the same over the pedestrians (NaN without any)", "sgjax"),
        robot_metric("invasiveness_speed", "m/s",
                     "the same for speeds: mean over steps and over the other robots and "
                     "pedestrians of |speed with - speed without this robot|", "sgjax"),
    )


COUNTERFACTUAL_NAMES = tuple(info.name for info in Counterfactual.infos)


@struct.dataclass
class SoloPaths:
    """Each robot's run alone in each episode: ``x, y [E, R, T + 1]`` (m, its position at every
    step, the start first; frozen once its run ended) and ``arrived_at [E, R]`` (int32 step it
    arrived alone; 0: it did not)."""

    x: Array
    y: Array
    arrived_at: Array


@struct.dataclass
class Tally:
    """Running comparisons for ``E`` episodes of ``R`` robots, ``[E, R]`` unless noted."""

    last_x: Array  # m: the robot's position in the episode before this step
    last_y: Array
    deviation_sum: Array  # m: sum over active steps of the distance to the solo path
    deviation_max: Array  # m
    deviation_steps: Array  # int32
    solo_cover: Array  # [E, R, T + 1] m: distance from each solo point to the path so far
    robots_sum: Array  # m: sum over steps of the mean gap of the other robots (without i)
    humans_sum: Array  # m: the same over pedestrians
    speed_sum: Array  # m/s: the same for speeds over all other bodies
    compared_steps: Array  # int32: steps the episode or the one without i ran


def start(x: Array, y: Array, solo: SoloPaths) -> Tally:
    """Empty comparisons; ``x, y [E, R]``: the robots' starts in the episode."""
    zf = jnp.zeros(x.shape, jnp.float32)
    zi = jnp.zeros(x.shape, jnp.int32)
    cover = safe_norm(solo.x - x[..., None], solo.y - y[..., None])
    return Tally(last_x=x, last_y=y, deviation_sum=zf, deviation_max=zf, deviation_steps=zi,
                 solo_cover=cover, robots_sum=zf, humans_sum=zf, speed_sum=zf,
                 compared_steps=zi)


def _to_solo_path(x: Array, y: Array, solo: SoloPaths) -> Array:
    """Distance (m) from points ``[E, R]`` to each robot's solo polyline: ``[E, R]``."""
    sq = point_segment_distance_sq(x[..., None], y[..., None], solo.x[..., :-1],
                                   solo.y[..., :-1], solo.x[..., 1:], solo.y[..., 1:])
    return jnp.sqrt(jnp.min(sq, axis=-1))


def update(c: Tally, solo: SoloPaths, prev: EnvState, state: EnvState, running: Array) -> Tally:
    """Compare one step. ``prev, state``: the lanes' states before and after it, leading axes
    ``[E, 1 + R]`` (lane 0 the episode, lane ``1 + i`` without robot ``i``); ``running [E, 1 + R]``:
    which lanes' episodes had not ended before the step."""
    full_prev, full = prev.robots, state.robots
    x, y = full.x[:, 0], full.y[:, 0]  # [E, R]
    was_active = full_prev.active[:, 0] & running[:, 0:1]
    gap = _to_solo_path(x, y, solo)
    # Distance from every solo point to the segment the robot moved along this step.
    step_gap = jnp.sqrt(point_segment_distance_sq(solo.x, solo.y, c.last_x[..., None],
                                                  c.last_y[..., None], x[..., None],
                                                  y[..., None]))
    cover = jnp.where(was_active[..., None], jnp.minimum(c.solo_cover, step_gap), c.solo_cover)

    # Invasiveness of robot i: the others with (lane 0) and without i (lane 1 + i).
    num_robots = x.shape[1]
    compared = running[:, 0:1] | running[:, 1:]  # [E, R(i)]
    present = full.present[:, 0]  # [E, R(j)]
    other_robot = present[:, None, :] & ~jnp.eye(num_robots, dtype=bool)[None]  # [E, i, j]
    robot_gap = safe_norm(full.x[:, 1:] - x[:, None, :], full.y[:, 1:] - y[:, None, :])
    humans = state.humans
    human_on = humans.active[:, 0]  # [E, H]
    human_gap = safe_norm(humans.x[:, 1:] - humans.x[:, 0:1], humans.y[:, 1:] - humans.y[:, 0:1])
    robot_speed = jnp.where(full.parked, 0.0, safe_norm(full.kin.v_forward,
                                                        full.kin.v_lateral))  # [E, L, R]
    human_speed = safe_norm(humans.vx, humans.vy)  # [E, L, H]
    robot_dspeed = jnp.abs(robot_speed[:, 1:] - robot_speed[:, 0:1])
    human_dspeed = jnp.abs(human_speed[:, 1:] - human_speed[:, 0:1])

    def mean_over(values: Array, mask: Array) -> Array:
        return (jnp.sum(jnp.where(mask, values, 0.0), axis=-1)
                / jnp.maximum(jnp.sum(mask, axis=-1), 1))

    human_mask = jnp.broadcast_to(human_on[:, None, :], human_gap.shape)
    robots_mean = mean_over(robot_gap, other_robot)
    humans_mean = mean_over(human_gap, human_mask)
    speed_total = (jnp.sum(jnp.where(other_robot, robot_dspeed, 0.0), axis=-1)
                   + jnp.sum(jnp.where(human_mask, human_dspeed, 0.0), axis=-1))
    speed_mean = speed_total / jnp.maximum(jnp.sum(other_robot, -1) + jnp.sum(human_mask, -1), 1)

    def add(total: Array, value: Array, mask: Array) -> Array:
        return total + jnp.where(mask, value, 0).astype(total.dtype)

    return Tally(
        last_x=x, last_y=y,
        deviation_sum=add(c.deviation_sum, gap, was_active),
        deviation_max=jnp.where(was_active, jnp.maximum(c.deviation_max, gap), c.deviation_max),
        deviation_steps=add(c.deviation_steps, 1, was_active),
        solo_cover=cover,
        robots_sum=add(c.robots_sum, robots_mean, compared),
        humans_sum=add(c.humans_sum, humans_mean, compared),
        speed_sum=add(c.speed_sum, speed_mean, compared),
        compared_steps=add(c.compared_steps, 1, compared),
    )


def finalize(c: Tally, solo: SoloPaths, final: EnvState, makespan: Array, params: EnvParams
             ) -> tuple[dict[str, Array], dict[str, Array]]:
    """The counterfactual metrics: ``({name: [E, R]}, {name: [E]})`` (NaN for robots not in
    the episode). ``final``: the episodes' final states (leading axis ``[E]``); ``makespan
    [E]`` (s, NaN unless a team success) from :func:`sgjax.evaluation.metrics.finalize`."""
    nan = jnp.float32(jnp.nan)
    present = final.robots.present  # [E, R]
    humans = final.humans.active  # [E, H]
    others = jnp.sum(present, axis=-1, keepdims=True) > 1  # [E, 1]
    steps = jnp.maximum(c.compared_steps, 1)
    moved = c.deviation_steps > 0
    robot = {
        "path_deviation_mean": jnp.where(moved, c.deviation_sum / jnp.maximum(
            c.deviation_steps, 1), 0.0),
        "path_deviation_max": c.deviation_max,
        "hausdorff": jnp.maximum(c.deviation_max, jnp.max(c.solo_cover, axis=-1)),
        "invasiveness_robots": jnp.where(others, c.robots_sum / steps, nan),
        "invasiveness_humans": jnp.where(jnp.any(humans, axis=-1, keepdims=True),
                                         c.humans_sum / steps, nan),
        "invasiveness_speed": jnp.where(others | jnp.any(humans, axis=-1, keepdims=True),
                                        c.speed_sum / steps, nan),
    }
    robot = {k: jnp.where(present, v, nan).astype(jnp.float32) for k, v in robot.items()}
    solo_done = jnp.all(~present | (solo.arrived_at > 0), axis=-1)
    slowest = jnp.max(jnp.where(present, solo.arrived_at, 0), axis=-1) * params.dt
    ratio = jnp.where(solo_done & (slowest > 0), makespan / jnp.maximum(slowest, 1e-6), nan)
    return robot, {"makespan_ratio": ratio.astype(jnp.float32)}
