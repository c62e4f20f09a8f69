"""Trained weights evaluated: lanes of weights (seeds, ablation variants, sweep trials) on
shared episodes of one scenario at several robot counts, greedy or sampled or both, and beside
baseline policies for paired comparisons.

A trained actor enters as an :class:`ActorSpec`: a hashable description of the network that
turns weights (any pytree, batched over lanes) into a
:class:`~sgjax.evaluation.policies.RecurrentPolicy` (``train.algorithm.actor.TrainedActor`` is
the trainer's). The weights are an argument of every compiled program, so a program does not
change with training: :class:`TrainedEvaluation` resolves the spec, the environment and its
params at every count once, each program is built once per static setting in a process, and
JAX's persistent compilation cache finds it again in the next run of the same job.

Two program layouts, chosen by what is asked:

* lanes of weights (no baselines): a :class:`~sgjax.evaluation.runner.ParamLaneRunner`, every
  lane playing the same episodes (the same keys), one play mode or several (the weights
  repeated, a traced flag per lane): ``{metric: [lanes, E]}`` or ``{metric: [modes, lanes,
  E]}``;
* one lane of weights beside baselines: a :class:`~sgjax.evaluation.runner.LaneRunner` whose
  configurations are the actor and each baseline at one count, on the same episodes (common
  random numbers: their differences pair episode by episode), optionally recording episodes.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Hashable, Sequence
from typing import Any, Protocol

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from sgjax.environment.options import MakeOptions
from sgjax.evaluation.evaluate import params_by_count
from sgjax.evaluation.policies import RecurrentPolicy, load_policy
from sgjax.evaluation.runner import LaneRunner, ParamLaneRunner, check_steps, compiled_once


class ActorSpec(Hashable, Protocol):
    """What :class:`TrainedEvaluation` needs of a trained actor: hashable (programs are kept
    per spec), the observation size it reads, and its policy for given weights."""

    @property
    def obs_size(self) -> int: ...

    def policy(self, weights: Any, deterministic: bool | Array) -> RecurrentPolicy:
        """The actor with ``weights`` (one lane's), greedy where ``deterministic`` (a Python
        bool, or a traced bool scalar: both computed, one chosen)."""
        ...


def check_observation_size(actor: ActorSpec, env: Any, where: str) -> None:
    """Refuse an environment whose observations are not the size ``actor`` reads, naming
    ``where`` (the scenario)."""
    if env.observation_size != actor.obs_size:
        raise ValueError(f"{where}: the trained policy reads observations of size "
                         f"{actor.obs_size}, this environment gives {env.observation_size}")


def _cached(build: Callable, *key: Any) -> Any:
    """``build(*key)``, kept for the process (and built again when ``key`` is unhashable)."""
    try:
        hash(key)
    except TypeError:
        return build.__wrapped__(*key)
    return build(*key)


def lane_count(weights: Any) -> int:
    """How many lanes lane-batched ``weights`` hold (the leading axis of its leaves)."""
    return int(np.shape(jax.tree.leaves(weights)[0])[0])


@functools.lru_cache(maxsize=16)
def _lanes_program(actor: ActorSpec, env: Any, episodes: int, num_steps: int,
                   modes: bool | tuple[bool, ...]) -> Callable:
    """``jit`` of a ``ParamLaneRunner`` over lane-batched weights for one play mode (``modes``
    a bool: static) or for a tuple of them (a traced flag per lane; outputs ``[modes, lanes,
    ...]``, the weights repeated mode-major). The lanes play inside one episode loop."""

    if isinstance(modes, bool):  # a lane is its weights
        def make_policy(lane: Any) -> RecurrentPolicy:
            return actor.policy(lane, modes)
    else:  # a lane is (weights, its traced mode)
        def make_policy(lane: Any) -> RecurrentPolicy:
            return actor.policy(*lane)

    def play(lanes: Any, key: Array, params: Any) -> tuple[dict, dict]:
        runner = ParamLaneRunner(env, make_policy, lanes, episodes, num_steps)
        values, robot, *_ = runner.episodes(key, params)
        return values, robot

    if isinstance(modes, bool):
        return jax.jit(play)

    def by_mode(weights: Any, key: Array, params: Any) -> tuple[dict, dict]:
        count = lane_count(weights)
        repeated = jax.tree.map(lambda x: jnp.concatenate([x] * len(modes)), weights)
        flags = jnp.repeat(jnp.asarray(modes), count)
        out = play((repeated, flags), key, params)
        return jax.tree.map(lambda x: x.reshape((len(modes), count) + x.shape[1:]), out)

    return jax.jit(by_mode)


@functools.lru_cache(maxsize=16)
def _table_program(actor: ActorSpec, env: Any, baselines: tuple[str, ...], num_counts: int,
                   episodes: int, num_steps: int, deterministic: bool,
                   record_lanes: tuple[tuple[int, int], ...] | None) -> Callable:
    """``jit`` of the ``LaneRunner`` of the actor (one lane's weights) and ``baselines``."""

    def run(weights: Any, key: Array, params: Any, counts: Array) -> tuple:
        policies = [actor.policy(weights, deterministic),
                    *(load_policy(name, env) for name in baselines)]
        runner = LaneRunner(env, policies, num_counts, episodes, num_steps,
                            record_lanes=record_lanes)
        return runner.episodes(key, params, counts)

    return jax.jit(run)


class TrainedEvaluation:
    """Trained weights on ``episodes`` shared episodes of ``scenario`` at each robot count of
    ``counts``, in the ``sgjax.make`` ``options`` with ``max_agents`` robot slots (default the
    options', else the largest count, as ``sgjax evaluate`` makes it): built once, called for
    any weights.

    ``modes``: one play mode (False samples actions, True takes the most likely) or a tuple
    of them (one program plays them all: a leading modes axis). :meth:`lanes` and
    :meth:`scores` play lanes of weights; :meth:`paired` plays one lane's weights beside the
    ``baselines`` (policy names) on the same episodes, recording the actor's episode 0 with
    ``record``."""

    def __init__(self, actor: ActorSpec, scenario: str, counts: Sequence[int], episodes: int,
                 options: MakeOptions, max_agents: int | None = None,
                 modes: bool | Sequence[bool] = False, baselines: Sequence[str] = (),
                 record: bool = False):
        self.counts = [int(n) for n in counts]
        self.options = options  # the make options every lane plays in
        if not self.counts:
            raise ValueError("TrainedEvaluation: no robot counts to evaluate at")
        self.env, self.params = params_by_count(
            scenario, self.counts, options=options,
            max_agents=max_agents or options.robots.max_agents or max(self.counts))
        check_observation_size(actor, self.env, scenario)
        self.modes = bool(modes) if isinstance(modes, bool | np.bool_) else tuple(
            bool(m) for m in modes)
        if self.modes == ():
            raise ValueError("TrainedEvaluation: modes names no play mode")
        self.actor, self.baselines, self.episodes = actor, tuple(baselines), int(episodes)
        self.record = bool(record)
        self.num_steps = int(self.params[self.counts[0]].max_steps)

    @property
    def _lanes_jit(self) -> Callable:
        return _cached(_lanes_program, self.actor, self.env, self.episodes, self.num_steps,
                       self.modes)

    @property
    def _table_jit(self) -> Callable:
        if not isinstance(self.modes, bool):
            raise ValueError("TrainedEvaluation.paired: plays one mode; built with "
                             f"{self.modes}")
        lanes = ((0, 0),) if self.record else None
        return _cached(_table_program, self.actor, self.env, self.baselines, 1, self.episodes,
                       self.num_steps, self.modes, lanes)

    def _checked(self, count: int) -> Any:
        if count not in self.params:
            raise ValueError(f"TrainedEvaluation: robot count {count} is not one of "
                             f"{self.counts}")
        params = self.params[count]
        check_steps(params, self.num_steps, "TrainedEvaluation")
        return params

    def lanes(self, weights: Any, key: Array, count: int) -> tuple[dict, dict]:
        """Every lane of lane-batched ``weights`` at ``count`` robots: ``(values, robot)``,
        ``{metric: [lanes, E]}`` and ``{metric: [lanes, E, R]}`` (a leading modes axis for a
        tuple of modes)."""
        return self._lanes_jit(weights, key, self._checked(count))

    def scores(self, weights: Any, key: Array, metric: str) -> np.ndarray:
        """``metric``'s mean over the episodes (NaN-aware), ``[counts, lanes]`` (one play
        mode)."""
        rows = []
        for n in self.counts:
            values, _ = self.lanes(weights, key, n)
            rows.append(np.nanmean(np.asarray(values[metric], np.float64), axis=-1))
        return np.stack(rows)

    def paired(self, weights: Any, key: Array, count: int) -> tuple[tuple, float]:
        """One lane's ``weights`` and every baseline at ``count`` robots on the same episodes:
        ``((values, robot, states, rewards), compile_s)``, ``values`` ``{metric: [1 + baselines,
        E]}`` (the actor first), ``states`` the recorded episode ``[T + 1, 1, ...]`` (None
        without ``record``), ``compile_s`` the seconds this call spent compiling."""
        self._checked(count)
        params = self.params[self.counts[0]]  # the count is the program's argument
        counts = jnp.asarray([count], jnp.int32)
        compiled, seconds = compiled_once(self._table_jit, weights, key, params, counts)
        return compiled(weights, key, params, counts), seconds
