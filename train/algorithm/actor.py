"""The trained actor as an ``sgjax`` policy: what it reads (:class:`ActorLayout`), its weights
(:class:`ActorWeights`) and the one function that turns both into a policy
(:func:`acting_policy`), used by ``Trainer.policy``, checkpoint loading and the evaluators.

The evaluators (:func:`lane_evaluator`: the seeds or variants of a run;
:func:`play_modes_evaluator`: the same, greedy and sampled, one program; :func:`table_evaluator`:
the actor and baselines at every robot count, one program) take the weights as an argument, so
their programs do not change with training: each is built once per process (and compiled once
per shape: :func:`compiled_once`), and JAX's persistent compilation cache finds it again in
the next run of the same job.

A checkpoint keeps the layout in its meta, so a saved actor is rebuilt from the file alone: the
network configuration, the parameters, the observation normalisation statistics and mask, and
the layout; no ``Trainer`` and no training environments.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from jax import Array

from sgjax.evaluation.policies import RecurrentPolicy, load_policy
from sgjax.evaluation.runner import (
    LaneRunner,
    ParamLaneRunner,
    argument_signature,
    check_steps,
)
from train.algorithm.config import NetworkConfig
from train.algorithm.networks import ActorCritic, OthersLayout, greedy, initial_carry, sample
from train.algorithm.normalize import RunningStats


@dataclasses.dataclass(frozen=True)
class ActorLayout:
    """What a trained actor reads and writes beside its weights."""

    obs_size: int  # D, the environment's observation size
    slots: int  # robot slots trained with (the width of the one-hot id with agent_id)
    discrete: bool  # GO/STOP logits, else a Gaussian over continuous actions
    action_dim: int  # the head's outputs: 2 logits, or the continuous action size
    normalize: bool  # observations normalised by the running statistics
    others: OthersLayout | None  # where the others block sits, for the others encoder

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ActorLayout:
        others = data.get("others")
        return cls(obs_size=int(data["obs_size"]), slots=int(data["slots"]),
                   discrete=bool(data["discrete"]), action_dim=int(data["action_dim"]),
                   normalize=bool(data["normalize"]),
                   others=None if others is None else OthersLayout(**others))


@struct.dataclass
class ActorWeights:
    """The acting part of a run: network parameters, observation statistics and the
    observation mask (``None``: every feature seen). Batched over seeds or lanes when it comes
    from a vmapped run (:meth:`seed` picks one)."""

    params: Any
    obs_stats: RunningStats
    obs_mask: Array | None = None

    @classmethod
    def of(cls, runner: Any) -> ActorWeights:
        """The acting part of a ``RunnerState`` (any batch shape)."""
        return cls(runner.params, runner.obs_stats, runner.obs_mask)

    @property
    def lanes(self) -> int:
        """How many seeds (or lanes) seed-batched weights hold."""
        return int(jnp.shape(self.obs_stats.mean)[0])

    def seed(self, index: int) -> ActorWeights:
        """Seed (or lane) ``index`` of seed-batched weights."""
        count = self.lanes
        if not 0 <= index < count:
            raise ValueError(f"seed index {index} out of range (the run has {count} seeds)")
        return jax.tree.map(lambda x: x[index], self)


def head_log_std(params: Any, discrete: bool) -> Array | None:
    """The continuous head's learned log standard deviation (None for GO/STOP)."""
    return None if discrete else params["params"]["log_std"]


def actor_features(network: NetworkConfig, layout: ActorLayout, obs_stats: RunningStats,
                   obs: Array) -> Array:
    """``obs [..., R, D]`` -> the actor's input ``[..., R, D (+ slots)]``: normalised, and with a
    one-hot robot id under ``network.agent_id``.

    The others' 0/1 ``mask`` feature passes unnormalised: the others encoders read which body
    slots are filled from it (``> 0.5``). Normalised, a flag that is almost always 1 became 0 or
    less (a constant one exactly 0), so the encoders saw no bodies and never learned (until
    2026-11-24)."""
    x = obs_stats.normalize(obs) if layout.normalize else obs
    others = layout.others
    if layout.normalize and others is not None and others.mask_column is not None:
        flags = others.start + others.mask_column + others.width * np.arange(others.k)
        x = x.at[..., flags].set(obs[..., flags])
    if network.agent_id:
        ids = jnp.eye(x.shape[-2], layout.slots)
        x = jnp.concatenate([x, jnp.broadcast_to(ids, x.shape[:-1] + (layout.slots,))], axis=-1)
    return x


def acting_policy(network: NetworkConfig, layout: ActorLayout, weights: ActorWeights,
                  deterministic: bool | Array = False) -> RecurrentPolicy:
    """The actor as an ``sgjax.evaluation.evaluate`` policy (any robot count; with ``agent_id`` at
    most ``layout.slots``): actions sampled from it, or its most likely ones with
    ``deterministic``; continuous actions clipped to [-1, 1]. ``deterministic`` is a Python
    bool (one branch compiled) or a traced bool scalar (both computed, one chosen: a ``vmap``
    over it plays both modes in one program, :func:`play_modes_evaluator`)."""
    model = ActorCritic(network, layout.action_dim, layout.discrete, layout.others)
    spread = head_log_std(weights.params, layout.discrete)

    def init(num_robots: int) -> Array:
        if network.agent_id and num_robots > layout.slots:
            raise ValueError(f"this policy was trained with a robot id for {layout.slots} "
                             f"slots; it cannot act for {num_robots} robots")
        return initial_carry(network, num_robots)[0]

    def step(carry: Array, obs: Array, key: Array, state: Any, params_env: Any):
        if weights.obs_mask is not None:
            obs = obs * weights.obs_mask
        x = actor_features(network, layout, weights.obs_stats, obs)
        starts = jnp.zeros((1, obs.shape[0]), bool)
        carry, out = model.apply(weights.params, carry, x[None], starts,
                                 method=ActorCritic.act)
        out = out[0]
        if isinstance(deterministic, bool | np.bool_):  # static: one branch compiled
            action = (greedy(out, layout.discrete) if deterministic
                      else sample(key, out, spread, layout.discrete))
        else:
            action = jnp.where(deterministic, greedy(out, layout.discrete),
                               sample(key, out, spread, layout.discrete))
        return carry, (action if layout.discrete else jnp.clip(action, -1.0, 1.0))

    return RecurrentPolicy(init=init, step=step)


def _cached(build: Callable, *key: Any) -> Any:
    """``build(*key)``, kept for the process (and built again when ``key`` is unhashable)."""
    try:
        hash(key)
    except TypeError:
        return build.__wrapped__(*key)
    return build(*key)


@functools.lru_cache(maxsize=16)
def _seed_lanes_program(network: NetworkConfig, layout: ActorLayout, env: Any, episodes: int,
                        num_steps: int, modes: bool | tuple[bool, ...]) -> Callable:
    """``jit`` of a :class:`sgjax.evaluation.runner.ParamLaneRunner` over lane-batched weights
    (see :func:`lane_evaluator`), for one play mode (``modes`` a bool: static) or for a tuple
    of them (a traced flag per lane; outputs ``[modes, lanes, ...]``); one per static setting
    in a process. The modes are more lanes of the same loop (the weights repeated,
    mode-major). The lanes play inside one episode loop; a ``vmap`` of one lane's
    ``EpisodeRunner`` batched the loop itself and took longer to trace and compile (a tiny
    MLP's 4 seeds: trace 1.3 -> 0.5 s)."""

    if isinstance(modes, bool):  # a lane is its weights
        def make_policy(lane: Any) -> RecurrentPolicy:
            return acting_policy(network, layout, lane, modes)
    else:  # a lane is (weights, its traced mode)
        def make_policy(lane: Any) -> RecurrentPolicy:
            return acting_policy(network, layout, *lane)

    def play(lanes: Any, key: Array, params: Any) -> tuple[dict, dict]:
        runner = ParamLaneRunner(env, make_policy, lanes, episodes, num_steps)
        values, robot, _ = runner.episodes(key, params)
        return values, robot

    if isinstance(modes, bool):
        return jax.jit(play)

    def by_mode(weights: ActorWeights, key: Array, params: Any) -> tuple[dict, dict]:
        count = weights.lanes
        repeated = jax.tree.map(lambda x: jnp.concatenate([x] * len(modes)), weights)
        flags = jnp.repeat(jnp.asarray(modes), count)
        out = play((repeated, flags), key, params)
        return jax.tree.map(lambda x: x.reshape((len(modes), count) + x.shape[1:]), out)

    return jax.jit(by_mode)


def lane_evaluator(network: NetworkConfig, layout: ActorLayout, env: Any, env_params: Any,
                   episodes: int, deterministic: bool = False):
    """A ``(weights, key, params=env_params) -> (values, robot)`` evaluating every lane (seed or
    variant) of lane-batched :class:`ActorWeights` at once, ``vmap``-ed over the lanes:
    ``values`` is ``{metric: [lanes, episodes]}``, ``robot`` ``{metric: [lanes, episodes, R]}``.
    Compiled once per shape: the weights and the environment params are arguments, so every
    robot count up to ``env.max_agents`` (same time limit) reuses one compilation, and
    evaluators of the same setting in one process share it. Each lane is played by an
    :class:`sgjax.evaluation.runner.EpisodeRunner` (chunks of steps until every episode has
    ended)."""
    return _evaluator(network, layout, env, env_params, episodes, bool(deterministic),
                      "lane_evaluator")


def play_modes_evaluator(network: NetworkConfig, layout: ActorLayout, env: Any, env_params: Any,
                         episodes: int, modes: Sequence[bool] = (False, True)):
    """:func:`lane_evaluator` for several play modes (``modes``: False samples, True takes the
    most likely action) in one compiled program: ``(weights, key, params) -> (values,
    robot)`` with a leading modes axis, ``{metric: [modes, lanes, episodes]}`` and ``{metric:
    [modes, lanes, episodes, R]}``. Every mode plays the same episodes (same keys), so the
    modes pair episode by episode; one compilation where one evaluator per mode took one each
    (``train.reproduce`` reports both modes of every cell)."""
    modes = tuple(bool(m) for m in modes)
    if not modes:
        raise ValueError("play_modes_evaluator needs at least one play mode")
    return _evaluator(network, layout, env, env_params, episodes, modes, "play_modes_evaluator")


def _evaluator(network: NetworkConfig, layout: ActorLayout, env: Any, env_params: Any,
               episodes: int, modes: bool | tuple[bool, ...], name: str):
    """The evaluator of :func:`lane_evaluator` (``modes`` a bool: no modes axis) and
    :func:`play_modes_evaluator` (a tuple: a leading modes axis)."""
    num_steps = int(env_params.max_steps)
    compiled = _cached(_seed_lanes_program, network, layout, env, episodes, num_steps, modes)

    def evaluate(weights: ActorWeights, key: Array, params: Any = None) -> tuple[dict, dict]:
        params = env_params if params is None else params
        env.check_params(params)
        check_steps(params, num_steps, name)
        return compiled(weights, key, params)

    return evaluate


@functools.lru_cache(maxsize=16)
def _table_program(network: NetworkConfig, layout: ActorLayout, env: Any,
                   baselines: tuple[str, ...], num_counts: int, episodes: int, num_steps: int,
                   deterministic: bool, record_lanes: tuple[tuple[int, int], ...] | None
                   ) -> Callable:
    """``jit`` of the :class:`LaneRunner` of :func:`table_evaluator`; one per static setting
    in a process."""

    def run(weights: ActorWeights, key: Array, params: Any, counts: Array) -> tuple:
        policies = [acting_policy(network, layout, weights, deterministic),
                    *(load_policy(name, env) for name in baselines)]
        runner = LaneRunner(env, policies, num_counts, episodes, num_steps,
                            record_lanes=record_lanes)
        return runner.episodes(key, params, counts)

    return jax.jit(run)


_COMPILED: dict[Any, Callable] = {}


def compiled_once(program: Callable, *args: Any) -> tuple[Callable, float]:
    """``program`` (a ``jax.jit`` function) compiled ahead of time for the shapes of ``args``,
    once per process: ``(executable, seconds this call spent compiling)`` (0 when it was
    compiled before; a program found in the persistent compilation cache counts its
    loading)."""
    key = (program, argument_signature(args))
    if key in _COMPILED:
        return _COMPILED[key], 0.0
    t0 = time.perf_counter()
    _COMPILED[key] = program.lower(*args).compile()
    return _COMPILED[key], time.perf_counter() - t0


def table_evaluator(network: NetworkConfig, layout: ActorLayout, env: Any, env_params: Any,
                    baselines: Sequence[str], num_counts: int, episodes: int,
                    deterministic: bool = False,
                    record_lanes: Sequence[tuple[int, int]] | None = None):
    """A ``(weights, key, counts, params=env_params) -> ((values, robot, states), compile_s)``
    playing the trained actor (one seed's :class:`ActorWeights`, an argument) and every
    baseline in ``baselines`` (names, :mod:`sgjax.evaluation.policies`) at each of the ``K =
    num_counts`` robot counts in ``counts`` (``[K]`` int32), ``episodes`` episodes each, as the
    lanes of one :class:`sgjax.evaluation.runner.LaneRunner`: one compiled program for the
    whole final table. Configuration ``p * K + k`` is policy ``p`` (0 the actor, ``1 + i``
    ``baselines[i]``) at ``counts[k]``; ``values`` is ``{metric: [C, episodes]}``, ``robot``
    ``{metric: [C, episodes, R]}``, ``states`` the ``record_lanes`` ``(configuration,
    episode)`` states ``[T + 1, len(record_lanes), ...]`` (None without). Every configuration
    plays the episodes an ``EpisodeRunner`` of its policy plays with the same key at that
    count; ``compile_s`` is the seconds this call spent compiling (0 once compiled). The final
    evaluation (``train.cli``) builds it with ``num_counts=1`` and calls it once per count:
    one program still, each count stopping with its own slowest episode, and on the 2-core
    CPU faster per step than every count as lanes of one call."""
    num_steps = int(env_params.max_steps)
    lanes = None if record_lanes is None else tuple((int(c), int(e)) for c, e in record_lanes)
    program = _cached(_table_program, network, layout, env, tuple(baselines), int(num_counts),
                      int(episodes), num_steps, bool(deterministic), lanes)

    def evaluate(weights: ActorWeights, key: Array, counts: Array, params: Any = None
                 ) -> tuple[tuple, float]:
        params = env_params if params is None else params
        counts = jnp.asarray(counts, jnp.int32)
        for n in np.asarray(counts).tolist():
            env.check_params(params.replace(num_agents=jnp.asarray(n, jnp.int32)))
        check_steps(params, num_steps, "table_evaluator")
        compiled, seconds = compiled_once(program, weights, key, params, counts)
        return compiled(weights, key, params, counts), seconds

    return evaluate
