"""Counterfactual metrics: the same episode played again with one robot alone, or without it.

A batched simulator can answer "what would this robot have done with nobody else around" and
"what did this robot do to the others" exactly, by playing extra lanes of the same episode:
same reset key (same starts, goals and pedestrians, :meth:`SocialNavEnv.reset_subset`), same
per-step keys, one robot kept or one removed. For ``E`` episodes of ``R`` robot slots the
evaluation plays (:func:`play_counterfactual`, the lane plan)

* ``E x R`` **alone** lanes first (lane ``i``: robot ``i`` alone; its path and arrival are kept
  as :class:`SoloPaths`), then
* ``E x (1 + R)`` lanes: the episode itself and, for each robot ``i``, the episode **without**
  it; :func:`update` compares them step by step against the solo paths.

So the counterfactual metrics cost about ``1 + 2R`` times a plain evaluation (21x at 10 robot
slots; ``bench/evaluation.py`` measures it). The metrics themselves, their definitions and
their accumulator are a registered metric family,
:mod:`sgjax.evaluation.metrics.counterfactuals`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import jax
import jax.numpy as jnp
from jax import Array

from sgjax.evaluation.metrics.accumulate import MetricState
from sgjax.evaluation.metrics.counterfactuals import SoloPaths, Tally, finalize, start, update
from sgjax.evaluation.metrics.paths import Paths
from sgjax.types import EnvParams, EnvState


def alone_masks(num_robots: int) -> Array:
    """``[R, R]`` bool: lane ``i`` keeps robot ``i`` only."""
    return jnp.eye(num_robots, dtype=bool)


def main_masks(num_robots: int) -> Array:
    """``[1 + R, R]`` bool: lane 0 keeps every robot (the episode itself), lane ``1 + i``
    every robot but ``i``."""
    return jnp.concatenate([jnp.ones((1, num_robots), bool),
                            ~jnp.eye(num_robots, dtype=bool)], axis=0)


class LanePlayer(Protocol):
    """What the lane plan needs from an episode runner
    (:class:`sgjax.evaluation.runner.EpisodeRunner` is one): ``E`` episodes of ``R`` robot
    slots, reset with a subset of the robots, played together as lanes of one batch."""

    num_episodes: int  # E
    num_robots: int  # R

    def reset_lanes(self, keys: Array, params: EnvParams, keep: Array
                    ) -> tuple[Array, EnvState]:
        """``env.reset_subset`` batched: ``keys [N]``, ``keep [N, R]`` bool."""

    def play(self, params: EnvParams, obs: Array, state: EnvState, lanes: int,
             step_keys: Array, hook: Callable | None = None, extra: Any = None,
             emit: Callable | None = None) -> tuple[EnvState, MetricState, Any, Any]:
        """Play ``E x lanes`` episodes (episode-major, the lanes of an episode sharing its
        per-step keys); ``hook(extra, prev, state, running)`` folds each step into ``extra``;
        ``emit(state)`` is returned for every step. Returns ``(final, tally, extra, out)``."""

    def finalize(self, tally: MetricState, final: EnvState, params: EnvParams
                 ) -> tuple[dict[str, Array], dict[str, Array]]:
        """Every lane's metrics (``metrics.finalize`` batched)."""


def by_episode(tree: Any, num_episodes: int, lanes: int) -> Any:
    """``[E * L, ...] -> [E, L, ...]`` for every leaf of ``tree``."""
    return jax.tree.map(lambda v: v.reshape((num_episodes, lanes) + v.shape[1:]), tree)


def play_alone(player: LanePlayer, reset_keys: Array, step_keys: Array, params: EnvParams
               ) -> SoloPaths:
    """Play every robot of every episode alone (lane ``i`` keeps robot ``i``) and keep its
    path and arrival step. ``reset_keys [E]``, ``step_keys [T]``."""
    episodes, lanes = player.num_episodes, player.num_robots
    own = jnp.arange(lanes)
    masks = jnp.tile(alone_masks(lanes), (episodes, 1))
    obs, state = player.reset_lanes(jnp.repeat(reset_keys, lanes, axis=0), params, masks)

    def own_xy(s: EnvState, reward: Array | None = None) -> Array:  # [E, R, 2]: i in lane i
        r = by_episode(s.robots, episodes, lanes)
        return jnp.stack([r.x[:, own, own], r.y[:, own, own]], axis=-1)

    _, alone, _, path = player.play(params, obs, state, lanes, step_keys, emit=own_xy)
    path = jnp.concatenate([own_xy(state)[None], path])  # [T + 1, E, R, 2]
    arrived_at = alone.tallies[Paths.__name__].arrived_at  # [E * R, R] step it arrived (0: not)
    arrived = by_episode(arrived_at, episodes, lanes)[:, own, own]
    return SoloPaths(x=jnp.moveaxis(path[..., 0], 0, -1), y=jnp.moveaxis(path[..., 1], 0, -1),
                     arrived_at=arrived)


def play_counterfactual(player: LanePlayer, reset_keys: Array, step_keys: Array,
                        params: EnvParams, record: bool = False) -> tuple:
    """The lane plan: every robot alone (:func:`play_alone`), then the episode (lane 0) and
    the episode without each robot (lane ``1 + i``) compared step by step.

    Returns ``(robot, episode, recorded, first)``: every metric, the counterfactual ones
    filled in (``{name: [E, R]}``, ``{name: [E]}``); with ``record`` the episodes' states after
    each step and the step's rewards, ``([T, E, ...], [T, E, R])`` (else None); ``first``,
    their states after the reset ``[E, ...]``."""
    episodes, num = player.num_episodes, player.num_robots
    solo = play_alone(player, reset_keys, step_keys, params)
    lanes = 1 + num
    masks = jnp.tile(main_masks(num), (episodes, 1))
    obs, state = player.reset_lanes(jnp.repeat(reset_keys, lanes, axis=0), params, masks)

    def compare(c: Tally, prev: EnvState, now: EnvState, running: Array) -> Tally:
        return update(c, solo, by_episode(prev, episodes, lanes),
                      by_episode(now, episodes, lanes), running.reshape(episodes, lanes))

    def episode_lane(tree: Any) -> Any:  # lane 0 of every episode
        return jax.tree.map(lambda v: v[::lanes], tree)

    def recorded_lane(state: EnvState, reward: Array) -> Any:
        return episode_lane((state, reward))

    first = by_episode(state.robots, episodes, lanes)
    c0 = start(first.x[:, 0], first.y[:, 0], solo)
    final, tally, c, out = player.play(params, obs, state, lanes, step_keys, hook=compare,
                                       extra=c0, emit=recorded_lane if record else None)
    final, tally = episode_lane((final, tally))
    robot, episode = player.finalize(tally, final, params)
    extra_robot, extra_episode = finalize(c, solo, final, episode["makespan"], params)
    return ({**robot, **extra_robot}, {**episode, **extra_episode}, out, episode_lane(state))
