"""The trained actor as an ``sgjax`` policy: what it reads (:class:`ActorLayout`), its weights
(:class:`ActorWeights`), its inputs (:func:`actor_features`, and the critic's beside them:
:func:`agent_inputs`) and the one function that turns layout and weights into a policy
(:func:`acting_policy`), used by ``Trainer.policy``, checkpoint loading and, through
:class:`TrainedActor`, every evaluation of trained weights
(:class:`sgjax.evaluation.trained.TrainedEvaluation`).

A checkpoint keeps the layout in its meta, so a saved actor is rebuilt from the file alone: the
network configuration, the parameters, the observation normalisation statistics and mask, and
the layout; no ``Trainer`` and no training environments.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from jax import Array

from sgjax.evaluation.policies import RecurrentPolicy
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
    less (a constant one exactly 0), so the encoders would see no bodies and never learn."""
    x = obs_stats.normalize(obs) if layout.normalize else obs
    others = layout.others
    if layout.normalize and others is not None and others.mask_column is not None:
        flags = others.start + others.mask_column + others.width * np.arange(others.k)
        x = x.at[..., flags].set(obs[..., flags])
    if network.agent_id:
        ids = jnp.eye(x.shape[-2], layout.slots)
        x = jnp.concatenate([x, jnp.broadcast_to(ids, x.shape[:-1] + (layout.slots,))], axis=-1)
    return x


def agent_inputs(network: NetworkConfig, layout: ActorLayout, mappo: bool,
                 obs_stats: RunningStats, obs: Array) -> tuple[Array, Array]:
    """The actor's and the critic's inputs ``[B, .]`` of a batch ``obs [E, R, D]`` (``B = E x
    R``): the actor's of :func:`actor_features`; the critic's the same under IPPO, and under
    MAPPO the global state, every robot's (normalised) observation of its environment
    concatenated, with the robot's one-hot id."""
    actor = actor_features(network, layout, obs_stats, obs)
    if mappo:
        x = obs_stats.normalize(obs) if layout.normalize else obs
        joint = x.reshape(x.shape[0], 1, -1)
        ids = jnp.broadcast_to(jnp.eye(layout.slots), x.shape[:-1] + (layout.slots,))
        critic = jnp.concatenate(
            [jnp.broadcast_to(joint, x.shape[:-1] + joint.shape[-1:]), ids], axis=-1)
    else:
        critic = actor
    flat = lambda v: v.reshape((-1, v.shape[-1]))  # noqa: E731
    return flat(actor), flat(critic)


def acting_policy(network: NetworkConfig, layout: ActorLayout, weights: ActorWeights,
                  deterministic: bool | Array = False) -> RecurrentPolicy:
    """The actor as an ``sgjax.evaluation.evaluate`` policy (any robot count; with ``agent_id`` at
    most ``layout.slots``): actions sampled from it, or its most likely ones with
    ``deterministic``; continuous actions clipped to [-1, 1]. ``deterministic`` is a Python
    bool (one branch compiled) or a traced bool scalar (both computed, one chosen: a ``vmap``
    over it plays both modes in one program, as ``TrainedEvaluation(modes=(...))`` does)."""
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


@dataclasses.dataclass(frozen=True)
class TrainedActor:
    """The trained actor's network and layout, as an
    :class:`sgjax.evaluation.trained.ActorSpec`: hashable, so that the evaluation programs of
    one actor are built once per process; its weights (:class:`ActorWeights`) are the
    programs' argument."""

    network: NetworkConfig
    layout: ActorLayout

    @property
    def obs_size(self) -> int:
        return self.layout.obs_size

    def policy(self, weights: ActorWeights, deterministic: bool | Array = False
               ) -> RecurrentPolicy:
        """:func:`acting_policy` of ``weights``."""
        return acting_policy(self.network, self.layout, weights, deterministic)
