"""The learning half of a PPO update: ``update_epochs`` passes of ``num_minibatches``
minibatches over one rollout, in one of two layouts that take the same minibatches and
optimiser steps:

* **masked**: every transition of a minibatch computed, the inactive ones masked out of the
  losses (:func:`train.algorithm.losses.masked_loss`);
* **compact** (``algorithm.compact``): only each minibatch's units that can learn are computed,
  whole chunks of ``1 / COMPACT_CHUNKS`` of it and then half chunks, each gathering its own
  units' data; the gradient is the masked one's up to float rounding.

A unit is one transition for a memoryless network, one agent's whole sequence for a GRU.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import optax
from jax import Array

from train.algorithm.config import AlgorithmConfig
from train.algorithm.lane_settings import LaneSettings
from train.algorithm.losses import LOSS_TERMS, chunk_loss, masked_loss, normalised_advantages
from train.algorithm.networks import ActorCritic
from train.algorithm.state import Rollout, Transition

# Eight chunks keep each chunk's products large while the padding of the last, half chunks
# stays under a sixteenth of a minibatch (bench/learner_roofline.py measures the layouts).
COMPACT_CHUNKS = 8


class Learner:
    """The learning phase of one trainer (one lane; a ``vmap`` adds lanes)."""

    def __init__(self, network: ActorCritic, optimizer: optax.GradientTransformation,
                 algorithm: AlgorithmConfig, settings: LaneSettings, num_agents: int,
                 discrete: bool, compact: bool, recurrent: bool):
        self.network, self.optimizer = network, optimizer
        self.algorithm, self.settings = algorithm, settings
        self.num_agents, self.discrete = num_agents, discrete
        self.compact = compact
        self.recurrent = recurrent  # memory along time (GRU): a unit is a sequence

    def learn(self, params: Any, opt_state: Any, key: Array, rollout: Rollout,
              hyper: dict) -> tuple[Any, Any, Array, dict]:
        """``update_epochs`` passes of ``num_minibatches`` minibatches: each epoch shuffles the
        agents once and cuts ``num_minibatches`` minibatches of ``num_agents /
        num_minibatches`` agents x ``num_steps`` steps. Returns the new parameters, optimiser
        state and key, and the loss terms ``[epochs, minibatches]``. ``hyper``: the lane's
        settings (:class:`~train.algorithm.lane_settings.LaneSettings`)."""
        if self.compact:
            step = lambda carry, batch: self.compact_step(  # noqa: E731
                carry, batch, rollout, hyper)
        else:
            step = lambda carry, batch: self.masked_step(carry, batch, hyper)  # noqa: E731
        cut = self.compact_batches if self.compact else self.masked_batches

        def epoch(carry, key):
            order = jax.random.permutation(key, self.num_agents)
            return jax.lax.scan(step, carry, cut(order, rollout))

        key, k_epochs = jax.random.split(key)
        (params, opt_state), aux = jax.lax.scan(
            epoch, (params, opt_state), jax.random.split(k_epochs, self.algorithm.update_epochs))
        return params, opt_state, key, aux

    def apply(self, params: Any, opt_state: Any, grads: Any, hyper: dict) -> tuple[Any, Any]:
        """One optimiser step at the lane's learning rate: Adam's step is proportional to its
        learning rate, so the configured schedule's step is scaled by ``hyper learning rate /
        algorithm.learning_rate`` (exactly 1 when the lane keeps the configured rate)."""
        updates, opt_state = self.optimizer.update(grads, opt_state, params)
        if "learning_rate" in self.settings.varied:
            scale = hyper["learning_rate"] / jnp.float32(self.algorithm.learning_rate)
            updates = jax.tree.map(lambda u: u * scale, updates)
        return optax.apply_updates(params, updates), opt_state

    # ------------------------------------------------------------------ masked
    def loss(self, params: Any, carry: tuple, traj: Transition, advantages: Array,
             targets: Array, hyper: dict | None = None) -> tuple[Array, dict]:
        """The masked loss of one minibatch (:func:`train.algorithm.losses.masked_loss`)."""
        return masked_loss(self.network, self.discrete, self.settings.loss_coefficients(hyper),
                           params, carry, traj, advantages, targets)

    def masked_batches(self, order: Array, rollout: Rollout) -> tuple:
        """Every minibatch of one epoch: the agents in ``order [B]`` (one gather), cut into
        ``M`` contiguous minibatches of ``U = B / M`` agents: ``(memory [M, U, H], traj
        [M, T, U, ...], advantages [M, T, U], targets [M, T, U])``."""
        minibatches = self.algorithm.num_minibatches
        size = self.num_agents // minibatches
        memory = jax.tree.map(lambda c: jnp.take(c, order, axis=0), rollout.memory)
        data = jax.tree.map(lambda x: jnp.take(x, order, axis=1),
                            (rollout.traj, rollout.advantages, rollout.targets))

        def cut_time_major(x):  # [T, B, ...] -> [M, T, B / M, ...]
            x = x.reshape((x.shape[0], minibatches, size) + x.shape[2:])
            return jnp.swapaxes(x, 0, 1)

        memory = jax.tree.map(
            lambda c: c.reshape((minibatches, size) + c.shape[1:]), memory)
        return (memory,) + jax.tree.map(cut_time_major, data)

    def masked_step(self, carry: tuple, batch: tuple, hyper: dict) -> tuple[tuple, dict]:
        """One optimiser step on one minibatch of :meth:`masked_batches`."""
        params, opt_state = carry
        memory, sub, adv, target = batch
        (_, aux), grads = jax.value_and_grad(self.loss, has_aux=True)(
            params, memory, sub, adv, target, hyper)
        return self.apply(params, opt_state, grads, hyper), aux

    # ------------------------------------------------------------------ compact
    def compact_batches(self, order: Array, rollout: Rollout) -> tuple[Array, Array]:
        """Every minibatch of one epoch as the indices of its units, those that can learn
        first: the same minibatches as :meth:`masked_batches`, reordered inside. Returns
        ``(units [M, U], counts [M])``, ``counts`` the units that can learn in each minibatch
        (a transition that is active; a sequence with some active step)."""
        minibatches = self.algorithm.num_minibatches
        active = rollout.traj.active  # [T, B]
        agents = order.reshape(minibatches, -1)  # [M, B / M]
        if self.recurrent:
            alive = jnp.any(active, axis=0)[agents]  # [M, U]
            return (jnp.take_along_axis(agents, active_first(alive), axis=1),
                    jnp.sum(alive, axis=1))
        rows = (jnp.arange(active.shape[0])[None, :, None] * self.num_agents
                + agents[:, None, :]).reshape(minibatches, -1)  # [M, U], time-major
        live = active.reshape(-1)[rows]
        return jnp.take_along_axis(rows, active_first(live), axis=1), jnp.sum(live, axis=1)

    def take_units(self, x: Array, units: Array) -> Array:
        """The entries of a rollout array ``x [T, B, ...]`` for ``units [C]``: ``[T, C, ...]``
        (agents' sequences) or ``[1, C, ...]`` (transitions)."""
        if self.recurrent:
            return jnp.take(x, units, axis=1)
        return x.reshape((-1,) + x.shape[2:])[units][None]

    def unit_data(self, rollout: Rollout, units: Array) -> tuple:
        """The learning data of ``units [C]`` but their advantages: ``(memory [C, H], traj
        [T', C, ...], targets [T', C])``, ``T' = T`` for a GRU, 1 otherwise (the memoryless
        network ignores the memory: zeros)."""
        if self.recurrent:
            memory = jax.tree.map(lambda c: c[units], rollout.memory)
        else:
            memory = jax.tree.map(lambda c: jnp.zeros(units.shape + c.shape[1:], c.dtype),
                                  rollout.memory)
        return (memory,) + jax.tree.map(lambda x: self.take_units(x, units),
                                        (rollout.traj, rollout.targets))

    def compact_step(self, carry: tuple, batch: tuple, rollout: Rollout, hyper: dict
                     ) -> tuple[tuple, dict]:
        """One optimiser step on one minibatch of :meth:`compact_batches`."""
        params, opt_state = carry
        grads, aux = self.compact_grads(params, batch, rollout, hyper)
        return self.apply(params, opt_state, grads, hyper), aux

    def compact_grads(self, params: Any, batch: tuple[Array, Array], rollout: Rollout,
                      hyper: dict | None = None) -> tuple[Any, dict]:
        """The loss gradient and terms of one minibatch ``batch = (units [U], count)``,
        computing only its first ``count`` units: whole chunks of ``U / COMPACT_CHUNKS``
        units, then the rest in half chunks (loops whose trip counts are the data's), each
        gathering its units' data and taking the gradient of its share of the masked losses
        (:func:`train.algorithm.losses.chunk_loss`), summed: :meth:`loss`'s gradient on the
        same minibatch up to float rounding."""
        units, count = batch
        chunk, half = compact_chunks(units.shape[0])
        traj = rollout.traj
        adv, counts = normalised_advantages(
            self.take_units(traj.active, units), self.take_units(traj.decides, units),
            self.take_units(rollout.advantages, units))
        coefficients = self.settings.loss_coefficients(hyper)

        def share_loss(params, memory, sub, share, targets):
            return chunk_loss(self.network, self.discrete, coefficients, params, memory, sub,
                              share, targets, counts)

        grad_fn = jax.grad(share_loss, has_aux=True)

        def add(start: Array, size: int, total: tuple) -> tuple:
            memory, sub, targets = self.unit_data(
                rollout, jax.lax.dynamic_slice_in_dim(units, start, size))
            share = jax.lax.dynamic_slice_in_dim(adv, start, size, axis=1)
            grads, aux = grad_fn(params, memory, sub, share, targets)
            return jax.tree.map(jnp.add, total, (grads, aux))

        zero = (jax.tree.map(jnp.zeros_like, params),
                {name: jnp.zeros((), jnp.float32) for name in LOSS_TERMS})
        whole, rest = compact_trips(count, chunk, half)
        total = jax.lax.fori_loop(0, whole, lambda i, t: add(i * chunk, chunk, t), zero)
        return jax.lax.fori_loop(0, rest, lambda i, t: add(whole * chunk + i * half, half, t),
                                 total)


def active_first(mask: Array) -> Array:
    """Indices ``[M, N]`` that put each row of ``mask [M, N]`` (bool) in the order: the true
    entries first, then the false ones, each in their original order (a stable partition,
    ``argsort(~mask, stable=True)``, by running counts and one scatter, which XLA:CPU runs
    faster than the sort)."""
    first = jnp.cumsum(mask, axis=-1) - 1
    rest = jnp.sum(mask, axis=-1, keepdims=True) + jnp.cumsum(~mask, axis=-1) - 1
    where = jnp.where(mask, first, rest)  # each entry's place
    index = jnp.broadcast_to(jnp.arange(mask.shape[-1]), mask.shape)
    rows = jnp.arange(mask.shape[0])[:, None]
    return jnp.zeros_like(index).at[rows, where].set(index, unique_indices=True)


def compact_chunks(units: int) -> tuple[int, int]:
    """The compact layout's chunk sizes for a minibatch of ``units`` units: ``(chunk, tail)``,
    ``chunk = units / d`` (``d`` the largest divisor of ``units`` up to
    :data:`COMPACT_CHUNKS`) and ``tail`` half a chunk (a whole one when ``chunk`` is odd): a
    divisor of ``chunk``, so that the tail chunks never run past the minibatch."""
    chunk = units // divisor_up_to(units, COMPACT_CHUNKS)
    return chunk, (chunk // 2 if chunk % 2 == 0 else chunk)


def compact_trips(count: Any, chunk: int, tail: int) -> tuple[Any, Any]:
    """How many whole chunks and then tail chunks compute ``count`` units (ints or arrays):
    ``(count // chunk, ceil((count mod chunk) / tail))``."""
    return count // chunk, -(-(count % chunk) // tail)


def divisor_up_to(n: int, most: int) -> int:
    """The largest divisor of ``n`` that is at most ``most``."""
    return max(d for d in range(1, most + 1) if n % d == 0)
