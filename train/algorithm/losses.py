"""The PPO loss as pure functions of explicit inputs: the clipped surrogate, the clipped value
loss and the entropy bonus over masked transitions, with advantages normalised over the
transitions whose action the environment read."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax.numpy as jnp
from jax import Array

from train.algorithm.actor import head_log_std
from train.algorithm.networks import ActorCritic, entropy, log_prob
from train.algorithm.state import Transition, critic_input

LOSS_TERMS = ("policy_loss", "value_loss", "entropy", "approx_kl")  # per minibatch


def normalised_advantages(active: Array, decides: Array, advantages: Array
                          ) -> tuple[Array, tuple[Array, Array]]:
    """A minibatch's advantages normalised over its acted transitions (``active``, and the
    action read: ``decides``; all ``[T', U]``), as :func:`masked_loss` does, and its counts of
    active and of acted transitions (at least 1 each): the whole-minibatch statistics every
    chunk's loss shares (the compact learning phase)."""
    def count(mask: Array) -> Array:
        return jnp.maximum(jnp.sum(mask.astype(jnp.float32)), 1.0)

    acted_mask = (active & decides).astype(jnp.float32)
    acted = count(acted_mask)
    adv_mean = jnp.sum(advantages * acted_mask) / acted
    adv_std = jnp.sqrt(jnp.sum(jnp.square(advantages - adv_mean) * acted_mask) / acted)
    return (advantages - adv_mean) / (adv_std + 1e-8), (count(active), acted)


def ppo_terms(network: ActorCritic, discrete: bool, coefficients: tuple[Any, Any, Any],
              params: Any, carry: tuple, traj: Transition, adv: Array, targets: Array,
              mean: Callable[[Array], Array], acted: Callable[[Array], Array]
              ) -> tuple[Array, dict]:
    """The PPO loss of ``traj [T, U, ...]`` and its terms (:data:`LOSS_TERMS`), with
    normalised advantages ``adv [T, U]``: ``mean`` averages (or, for a chunk, sums into a
    share of) the critic's terms over the active steps, ``acted`` the actor's over the steps
    whose action was read. ``coefficients``: ``(clip_eps, vf_coef, ent_coef)``, numbers or a
    lane's float32 scalars. ``carry``: the network memory at the first step, ``[U, H]``."""
    clip_eps, vf_coef, ent_coef = coefficients
    _, out, value = network.apply(params, carry, traj.actor_in, critic_input(traj), traj.starts)
    log_std = head_log_std(params, discrete)
    logp = log_prob(out, log_std, traj.action, discrete)
    ratio = jnp.exp(logp - traj.logp)
    policy_loss = -acted(jnp.minimum(ratio * adv, jnp.clip(ratio, 1.0 - clip_eps,
                                                           1.0 + clip_eps) * adv))
    clipped = traj.value + jnp.clip(value - traj.value, -clip_eps, clip_eps)
    value_loss = 0.5 * mean(jnp.maximum(jnp.square(value - targets),
                                        jnp.square(clipped - targets)))
    ent = acted(entropy(out, log_std, discrete))
    total = policy_loss + vf_coef * value_loss - ent_coef * ent
    approx_kl = acted((ratio - 1.0) - jnp.log(ratio))
    return total, {"policy_loss": policy_loss, "value_loss": value_loss, "entropy": ent,
                   "approx_kl": approx_kl}


def masked_loss(network: ActorCritic, discrete: bool, coefficients: tuple[Any, Any, Any],
                params: Any, carry: tuple, traj: Transition, advantages: Array, targets: Array
                ) -> tuple[Array, dict]:
    """:func:`ppo_terms` of a whole minibatch: the critic learns every active step, the actor
    only the steps whose action the environment read (all of them unless ``make``'s
    ``decision_period`` holds actions); advantages normalised over the latter. It is the one
    chunk of the minibatch that is the whole of it (:func:`chunk_loss`)."""
    adv, counts = normalised_advantages(traj.active, traj.decides, advantages)
    return chunk_loss(network, discrete, coefficients, params, carry, traj, adv, targets,
                      counts)


def chunk_loss(network: ActorCritic, discrete: bool, coefficients: tuple[Any, Any, Any],
               params: Any, carry: tuple, traj: Transition, adv: Array, targets: Array,
               counts: tuple[Array, Array]) -> tuple[Array, dict]:
    """A chunk's share of :func:`masked_loss` (``traj [T', C, ...]``): the sums of its
    transitions' loss terms divided by the whole minibatch's ``counts`` (active, acted), with
    ``adv`` already normalised over the minibatch (:func:`normalised_advantages`); the shares
    of a minibatch's chunks add up to its loss."""
    active, acted = counts
    acted_mask = traj.active & traj.decides
    return ppo_terms(network, discrete, coefficients, params, carry, traj, adv, targets,
                     lambda x: jnp.sum(x * traj.active) / active,
                     lambda x: jnp.sum(x * acted_mask) / acted)
