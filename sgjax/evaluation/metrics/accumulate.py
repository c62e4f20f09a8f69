"""The metric accumulators of one environment, composed over the registered metric families.

::

    m = metrics.start(env.max_agents)
    obs, next_state, reward, term, trunc, info = env.step_env(key, state, actions, params)
    done = metrics.episode_done(next_state, term, trunc)
    m = metrics.update(m, state, next_state, info, done, params)
    ...
    robot, episode = metrics.finalize(m, final_state, params)
    values = metrics.per_episode(robot, episode)

Each step builds one :class:`~sgjax.evaluation.metrics.step_view.StepView` that every family
reads, so quantities several metrics need (gaps, speeds, who is active) are computed once.
"""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp
import numpy as np
from flax import struct
from jax import Array

from sgjax.evaluation.metrics.base import NAN
from sgjax.evaluation.metrics.constants import DEFAULT_CONSTANTS, MetricConstants
from sgjax.evaluation.metrics.registration import METRICS
from sgjax.evaluation.metrics.step_view import EpisodeEnd, StepView
from sgjax.types import EnvParams, EnvState, episode_params


@struct.dataclass
class MetricState:
    """Per-step accumulators of one environment: what every family shares, and each
    registered family's own accumulator under its key (``tallies``)."""

    running: Array  # bool scalar: the episode has not ended
    length: Array  # int32 scalar: steps the episode ran
    active_steps: Array  # [R] int32: steps each robot was active
    tallies: dict[str, Any]  # family key -> its accumulator


def start(num_robots: int, constants: MetricConstants = DEFAULT_CONSTANTS, num_zones: int = 0
          ) -> MetricState:
    """Empty accumulators for a fresh episode of ``num_robots`` robot slots and ``num_zones``
    tracked conflict zones (``state.zones.phase.shape[1]``; 0 without zone books)."""
    return MetricState(
        running=jnp.ones((), bool), length=jnp.zeros((), jnp.int32),
        active_steps=jnp.zeros(num_robots, jnp.int32),
        tallies={f.key: f.start(num_robots, num_zones, constants) for f in METRICS.families()
                 if f.per_step})


def episode_done(state: EnvState, terminated: Array, truncated: Array) -> Array:
    """Whether every robot of the episode is done after a step (bool scalar)."""
    return jnp.all(~state.robots.present | terminated | truncated)


def update(m: MetricState, prev: EnvState, state: EnvState, info: dict, done: Array,
           params: EnvParams, constants: MetricConstants = DEFAULT_CONSTANTS) -> MetricState:
    """Accumulate one step ``prev -> state`` (``info`` from ``env.step_env``; ``done`` from
    :func:`episode_done`). Steps after the episode ended change no metric. The metrics read
    the episode's params (its generated world's map, if any)."""
    view = StepView(prev, state, info, done, episode_params(state, params), constants,
                    m.running)
    tallies = {f.key: f.update(m.tallies[f.key], view) for f in METRICS.families()
               if f.per_step}
    return MetricState(running=m.running & ~done,
                       length=jnp.where(m.running, state.time, m.length),
                       active_steps=view.add(m.active_steps, 1), tallies=tallies)


def finalize(m: MetricState, state: EnvState, params: EnvParams
             ) -> tuple[dict[str, Array], dict[str, Array]]:
    """Metrics of a finished episode from its accumulators and its final state.

    Returns ``(robot, episode)``: ``{name: [R]}`` float32 for robot-level metrics (NaN for
    robots not in the episode) and ``{name: scalar}`` float32 for episode-level ones, every
    registered metric in catalogue order. Metrics not computed from the step (``per_step``
    False: the counterfactual ones) read NaN here; the runner fills them in when it plays
    their lanes."""
    end = EpisodeEnd(state, episode_params(state, params), m.length, m.active_steps)
    present = state.robots.present
    robot, episode = {}, {}
    for family in METRICS.families():
        values = (family.finalize(m.tallies[family.key], end) if family.per_step
                  else {name: NAN for name in family.names})
        missing = sorted(set(family.names) - set(values))
        if missing:
            raise ValueError(f"{family.key}.finalize gave no value for {missing}")
        for info in family.infos:
            value = jnp.asarray(values[info.name], jnp.float32)
            if info.level == "robot":
                robot[info.name] = jnp.broadcast_to(value, present.shape)
            else:
                episode[info.name] = value
    # Robots not in the episode read NaN: one select for every robot-level metric at once.
    names = list(robot)
    masked = jnp.where(present, jnp.stack([robot[name] for name in names]), NAN)  # [M, R]
    return dict(zip(names, masked, strict=True)), episode


def per_episode(robot: dict[str, Array], episode: dict[str, Array]) -> dict[str, Array]:
    """One value per metric for an episode, in catalogue order: robot-level metrics reduced
    over the robots that have a value (mean or sum; NaN when none has). Batched inputs
    (``[..., R]`` and ``[...]``) give ``[...]``."""
    infos = [info for info in METRICS if info.level == "robot"]
    x = jnp.stack([robot[info.name] for info in infos], axis=-2)  # [..., M, R]: all at once
    has = jnp.isfinite(x)
    total = jnp.sum(jnp.where(has, x, 0.0), axis=-1)
    count = jnp.sum(has, axis=-1)
    summed = np.array([info.reduce == "sum" for info in infos])
    value = jnp.where(summed, total, total / jnp.maximum(count, 1))
    value = jnp.where(count > 0, value, jnp.nan)  # [..., M]
    reduced = {info.name: value[..., i] for i, info in enumerate(infos)}
    return {info.name: episode[info.name] if info.level == "episode" else reduced[info.name]
            for info in METRICS}
