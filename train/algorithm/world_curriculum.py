"""The trainer's curriculum over generated worlds (``levels`` in a config): one level buffer
per generated scenario of the environment batch, the levels of the next episodes written into
the environments' states before a rollout (:func:`choose_levels`), and the episodes that ended
in it scored and recorded after GAE (:func:`record_levels`). The buffers live in the runner
state, so every lane (seed) keeps its own curriculum; :mod:`train.algorithm.level_buffer`
holds the pure buffer functions."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array

from train.algorithm.config import LevelsConfig
from train.algorithm.env_batch import EnvBatch
from train.algorithm.level_buffer import (
    Crowd,
    LevelBuffer,
    episode_scores,
    next_levels,
    record,
    step_scores,
)

# The buffers' statistics an update logs (record_levels; progress.csv's extra columns)
LEVEL_STATS = ("levels_fill", "levels_replayed", "levels_score")


def empty_buffers(batch: EnvBatch, levels: LevelsConfig) -> tuple[LevelBuffer | None, ...]:
    """An empty buffer for every scenario whose worlds the trainer picks (None for the
    others), or ``()`` without a curriculum."""
    if not levels.active:
        return ()
    return tuple(None if source is None else LevelBuffer.empty(
        tuple(source.family.parameters), levels.buffer_size, size)
        for source, size in zip(batch.level_sources, batch.sizes, strict=True))


def crowds(batch: EnvBatch, levels: LevelsConfig) -> tuple[Crowd, ...]:
    """Per scenario of the batch, the pedestrian groups an ACCEL edit may add: groups of
    ``levels.pedestrian_group`` on top of the scenario's ``num_humans``, up to its
    ``max_humans`` (none in an environment without pedestrians)."""
    return tuple(Crowd(group=levels.pedestrian_group,
                       base=int(params.humans.num_humans) if env.config.humans.max_humans
                       else 0, capacity=int(env.config.humans.max_humans))
                 for env, params in zip(batch.envs, batch.params, strict=True))


def choose_levels(batch: EnvBatch, levels: LevelsConfig, key: Array, buffers: tuple,
                  env_states: tuple, now: Array, lane: dict) -> tuple[tuple, tuple]:
    """Every picked scenario's next levels written into its environments' states
    (``EnvState.next_level``) where the last pick was played (an environment whose episode
    has not ended since keeps its pick): ``(buffers, env_states)``. ``lane``: the lane's
    ``replay_prob`` and ``mutate_prob`` (:meth:`LevelsConfig.lane_values`)."""
    out_buffers, out_states = [], []
    keys = jax.random.split(key, len(batch.sizes))
    for source, buffer, state, k, crowd in zip(batch.level_sources, buffers, env_states, keys,
                                               crowds(batch, levels), strict=True):
        if source is None:
            out_buffers.append(buffer)
            out_states.append(state)
            continue
        ranges = {name: (low, high) for name, low, high in source.ranges}
        level = next_levels(
            k, buffer, now, ranges, replay_prob=lane["replay_prob"], min_fill=levels.min_fill,
            temperature=levels.temperature, staleness=levels.staleness,
            mutate_prob=lane["mutate_prob"], edits=levels.edits, edit_scale=levels.edit_scale,
            crowd=crowd)
        pending = state.next_level.chosen  # [E]; every leaf of a Level is [E]
        level = jax.tree.map(lambda old, new, pending=pending: jnp.where(pending, old, new),
                             state.next_level, level)
        out_buffers.append(buffer)
        out_states.append(state.replace(next_level=level))
    return tuple(out_buffers), tuple(out_states)


def played_levels(batch: EnvBatch, env_states: tuple) -> tuple:
    """The level each environment is playing, per picked scenario (``(seed, values,
    pedestrians, valid)``, ``[E_s]`` each; None for the others): what a step's episode ends
    on."""
    return tuple(None if source is None else (state.world.seed, state.world.values,
                                              state.world.pedestrians, state.world.valid)
                 for source, state in zip(batch.level_sources, env_states, strict=True))


def record_levels(batch: EnvBatch, buffers: tuple, now: Array, advantages: Array,
                  active: Array, ended: dict, lane: dict) -> tuple[tuple, dict]:
    """The buffers after a rollout: every episode that ended scored (its positive value
    loss from ``advantages [T, B]`` over ``active [T, B]``, or its learnability where the
    lane's ``learnability`` is 1) and recorded. ``ended``: the
    rollout's ``{"done": [T, E], "success": [T, E], "played": per scenario [T, E_s]}``.
    Returns the buffers and their statistics (means over the picked scenarios): ``fill``,
    ``replayed`` (share of the episodes recorded in the rollout that replayed a held level)
    and ``score`` (mean score of the held levels)."""
    num_envs = sum(batch.sizes)
    scores, stepped = step_scores(advantages, active, num_envs)
    by_scenario = [batch.split(x, axis=1)  # [T, E_s] each
                   for x in (scores, stepped, ended["done"], ended["success"])]
    parts = zip(batch.level_sources, buffers, *by_scenario, ended["played"], strict=True)
    out, stats = [], []
    for source, buffer, score, acted, done, success, played in parts:
        if source is None:
            out.append(buffer)
            continue
        episode, buffer = episode_scores(buffer, score, acted, done)
        seed, values, pedestrians, valid = played
        buffer, episodes, replays = record(
            buffer, now, seed, values, pedestrians, valid, done, episode, success,
            learnability=lane["learnability"] > 0.5,
            candidates=2 * buffer.episode_score.shape[0])
        out.append(buffer)
        held = jnp.where(buffer.filled, buffer.score, 0.0)
        stats.append((buffer.fill, replays / jnp.maximum(episodes, 1.0),
                      jnp.sum(held) / jnp.maximum(jnp.sum(buffer.filled), 1)))
    means = [jnp.mean(jnp.stack(column)) for column in zip(*stats, strict=True)]
    return tuple(out), dict(zip(LEVEL_STATS, means, strict=True))
