"""Actor-critic networks (Flax linen) for robots that share one set of weights.

Inputs are sequences: ``obs [T, B, D]`` for ``B`` robots (environments x robot slots, flattened)
and ``starts [T, B]`` (the step begins an episode, so recurrent state is reset). Layers:

1. optional *others encoder* pooling the ``others`` observation block (``k`` bodies x ``width``
   features, nearest first) into a fixed vector: ``attention`` (a query from the robot's own
   features, masked softmax over the bodies) or ``lstm`` (an LSTM over the bodies farthest first,
   so the nearest is read last, as CADRL-LSTM / SocialGym's custom layer);
2. optional GRU (``kind: gru``), its state reset where ``starts``;
3. an MLP, then the head: GO/STOP logits, or a Gaussian mean in [-1, 1] (tanh) with a learned
   state-independent log standard deviation; the critic's head is one value.

The actor and the critic are separate towers; under MAPPO the critic reads the global state.
With ``shared_encoder`` (decentralised critic only) one others encoder feeds both towers, as
SB3 shares its features extractor: half the encoder's work per sample.
"""

from __future__ import annotations

import dataclasses
import functools

import flax.linen as nn
import jax
import jax.numpy as jnp
from jax import Array

from sgjax.observations.columns import ObservationColumns
from train.algorithm.config import NetworkConfig
from train.algorithm.initializers import orthogonal

OTHERS = "others"  # the observation term the others encoders read


@dataclasses.dataclass(frozen=True)
class OthersLayout:
    """Where the ``others`` block sits in the observation vector: ``k`` bodies x ``width``
    features from column ``start``, read from the observation's published column layout
    (:meth:`from_columns`); saved with a trained actor (``train.algorithm.actor.ActorLayout``)."""

    start: int
    k: int
    width: int
    mask_column: int | None  # column of the 0/1 mask feature inside a body's block, if observed

    @classmethod
    def from_columns(cls, columns: ObservationColumns) -> OthersLayout | None:
        """The layout of the ``others`` term in an observation's column layout
        (``observer.columns(layout)``), or None without the term."""
        if OTHERS not in columns:
            return None
        block = columns[OTHERS]
        mask = block.offset("mask") if "mask" in block.feature_names else None
        return cls(columns.span(OTHERS).start, block.repeat, block.width, mask)

    @property
    def stop(self) -> int:
        return self.start + self.k * self.width


def others_layout(env) -> OthersLayout | None:
    """The layout of ``env``'s ``others`` observation term, or None without one."""
    return OthersLayout.from_columns(env.config.observer.columns(env.config.layout))


def most_seen(env) -> int | None:
    """The most ``others`` slots that can hold a body in ``env`` (None without the term; the
    column layout's ``filled``): a network built for ``env`` alone may skip the slots past it,
    which are always empty. Not part of the saved :class:`OthersLayout`: the same weights run
    in an environment with more robots, where every slot counts."""
    columns = env.config.observer.columns(env.config.layout)
    if OTHERS not in columns:
        return None
    block = columns[OTHERS]
    return block.repeat if block.filled is None else block.filled


def _activation(name: str):
    return nn.tanh if name == "tanh" else nn.relu


def _dense(size: int, scale: float = 2 ** 0.5) -> nn.Dense:
    return nn.Dense(size, kernel_init=orthogonal(scale),
                    bias_init=nn.initializers.zeros)


class OthersEncoder(nn.Module):
    """``[..., D] -> [..., own + size]``: own features, and the others block pooled.

    ``bodies``: the LSTM reads only the first ``bodies`` slots (None: all ``k``), for an
    environment where the later ones are always empty (:func:`most_seen`); an empty slot leaves
    the LSTM's state as it was, so the result is the same, bit for bit, at less cost."""

    layout: OthersLayout
    kind: str
    size: int
    bodies: int | None = None

    @nn.compact
    def __call__(self, obs: Array) -> Array:
        lay = self.layout
        own = jnp.concatenate([obs[..., :lay.start], obs[..., lay.stop:]], axis=-1)
        bodies = obs[..., lay.start:lay.stop].reshape(obs.shape[:-1] + (lay.k, lay.width))
        if lay.mask_column is None:
            valid = jnp.any(bodies != 0.0, axis=-1)
        else:
            valid = bodies[..., lay.mask_column] > 0.5
        if self.kind == "attention":
            embedded = nn.tanh(_dense(self.size)(bodies))  # [..., k, size]
            query = _dense(self.size)(own)[..., None, :]
            scores = jnp.sum(embedded * query, axis=-1) / jnp.sqrt(self.size)
            scores = jnp.where(valid, scores, -1e9)
            weights = jax.nn.softmax(scores, axis=-1) * valid
            values = _dense(self.size)(embedded)
            pooled = jnp.sum(weights[..., None] * values, axis=-2)
        else:  # LSTM over the bodies, farthest first; empty slots leave the state unchanged
            cell = nn.OptimizedLSTMCell(self.size, recurrent_kernel_init=orthogonal())
            zeros = jnp.zeros(bodies.shape[:-2] + (self.size,), bodies.dtype)
            carry = (zeros, zeros)  # (cell, hidden) at rest: no key drawn for zeros
            read = lay.k if self.bodies is None else min(max(self.bodies, 1), lay.k)
            for j in reversed(range(read)):
                new_carry, _ = cell(carry, bodies[..., j, :])
                keep = valid[..., j, None]
                carry = jax.tree.map(lambda n, o, keep=keep: jnp.where(keep, n, o),
                                     new_carry, carry)
            pooled = carry[1]
        return jnp.concatenate([own, pooled], axis=-1)


class ResetGRU(nn.Module):
    """A GRU over ``[T, B, F]`` whose state is zeroed where ``starts [T, B]``."""

    size: int

    @functools.partial(nn.scan, variable_broadcast="params", in_axes=0, out_axes=0,
                       split_rngs={"params": False})
    @nn.compact
    def __call__(self, carry: Array, inputs: tuple[Array, Array]) -> tuple[Array, Array]:
        x, starts = inputs
        carry = jnp.where(starts[:, None], jnp.zeros_like(carry), carry)
        carry, y = nn.GRUCell(self.size, recurrent_kernel_init=orthogonal())(carry, x)
        return carry, y


class ResetLSTM(nn.Module):
    """An LSTM over ``[T, B, F]`` whose memory is zeroed where ``starts [T, B]``; the carry is
    the cell and hidden states side by side, ``[B, 2 x size]`` (``c`` first), so that it
    travels as one array like a GRU's. The gates are torch's ``nn.LSTM`` (input, forget, cell,
    output; one bias per gate where torch keeps two that add up)."""

    size: int

    @functools.partial(nn.scan, variable_broadcast="params", in_axes=0, out_axes=0,
                       split_rngs={"params": False})
    @nn.compact
    def __call__(self, carry: Array, inputs: tuple[Array, Array]) -> tuple[Array, Array]:
        x, starts = inputs
        carry = jnp.where(starts[:, None], jnp.zeros_like(carry), carry)
        cell, hidden = carry[:, :self.size], carry[:, self.size:]
        (cell, hidden), y = nn.LSTMCell(self.size, recurrent_kernel_init=orthogonal())(
            (cell, hidden), x)
        return jnp.concatenate([cell, hidden], axis=-1), y


class Tower(nn.Module):
    """Encoder, optional recurrence over time and MLP: ``(carry [B, H], x [T, B, D], starts)
    -> (carry, features [T, B, F])``. ``gru``: a dense layer of ``recurrent_size`` then a GRU;
    ``lstm``: an LSTM of ``recurrent_size`` straight on the (encoded) observation, as
    sb3-contrib's ``MlpLstmPolicy`` puts it after its features extractor."""

    config: NetworkConfig
    layout: OthersLayout | None
    bodies: int | None = None

    @nn.compact
    def __call__(self, carry: Array, x: Array, starts: Array) -> tuple[Array, Array]:
        c = self.config
        act = _activation(c.activation)
        if self.layout is not None and c.others_encoder != "none":
            x = OthersEncoder(self.layout, c.others_encoder, c.encoder_size, self.bodies)(x)
        if c.kind == "gru":
            x = act(_dense(c.recurrent_size)(x))
            carry, x = ResetGRU(c.recurrent_size)(carry, (x, starts))
        elif c.kind == "lstm":
            carry, x = ResetLSTM(c.recurrent_size)(carry, (x, starts))
        for size in c.hidden:
            x = act(_dense(size)(x))
        return carry, x


class ActorCritic(nn.Module):
    """``(carry, actor_in [T, B, D], critic_in [T, B, G], starts [T, B]) -> (carry, out,
    value [T, B])`` with ``out`` the logits ``[T, B, 2]`` (discrete) or the mean
    ``[T, B, A]`` (continuous; ``log_std`` is a parameter). ``act`` runs the actor alone."""

    config: NetworkConfig
    action_dim: int
    discrete: bool
    layout: OthersLayout | None
    centralised: bool = False
    bodies: int | None = None  # see OthersEncoder: set only for the environment it was built for

    @property
    def shares_encoder(self) -> bool:
        """One others encoder feeds both towers (``config.shared_encoder``, decentralised)."""
        c = self.config
        return (c.shared_encoder and self.layout is not None and c.others_encoder != "none"
                and not self.centralised)

    def setup(self) -> None:
        if self.shares_encoder:
            c = self.config
            self.encoder = OthersEncoder(self.layout, c.others_encoder, c.encoder_size,
                                         self.bodies)
            self.actor = Tower(c, None)
            self.critic = Tower(c, None)
        else:
            self.actor = Tower(self.config, self.layout, self.bodies)
            self.critic = Tower(self.config, None if self.centralised else self.layout,
                                self.bodies)
        self.actor_head = _dense(self.action_dim, 0.01)
        self.critic_head = _dense(1, 1.0)
        if not self.discrete:
            self.log_std = self.param("log_std", nn.initializers.constant(-0.5),
                                      (self.action_dim,))

    def __call__(self, carry: tuple[Array, Array], actor_in: Array, critic_in: Array,
                 starts: Array) -> tuple[tuple[Array, Array], Array, Array]:
        if self.shares_encoder:  # the critic reads the actor's input: encode it once
            actor_in = critic_in = self.encoder(actor_in)
        actor_carry, out = self._act(carry[0], actor_in, starts)
        critic_carry, critic = self.critic(carry[1], critic_in, starts)
        return (actor_carry, critic_carry), out, self.critic_head(critic)[..., 0]

    def value(self, carry: Array, actor_in: Array, critic_in: Array, starts: Array
              ) -> tuple[Array, Array]:
        """The critic alone: ``(critic carry [B, H], actor_in [T, B, D], critic_in [T, B, G],
        starts [T, B]) -> (critic carry, value [T, B])``, the numbers ``__call__`` gives
        without the actor's work (``actor_in`` is read only by a shared encoder)."""
        if self.shares_encoder:
            critic_in = self.encoder(actor_in)
        carry, critic = self.critic(carry, critic_in, starts)
        return carry, self.critic_head(critic)[..., 0]

    def act(self, carry: Array, actor_in: Array, starts: Array) -> tuple[Array, Array]:
        if self.shares_encoder:
            actor_in = self.encoder(actor_in)
        return self._act(carry, actor_in, starts)

    def _act(self, carry: Array, actor_in: Array, starts: Array) -> tuple[Array, Array]:
        carry, actor = self.actor(carry, actor_in, starts)
        out = self.actor_head(actor)
        return carry, (out if self.discrete else nn.tanh(out))


def carry_size(config: NetworkConfig) -> int:
    """The width of one tower's recurrent state: ``recurrent_size`` for a GRU, twice it for an
    LSTM (cell and hidden), 1 (a dummy) for an MLP."""
    return {"gru": config.recurrent_size, "lstm": 2 * config.recurrent_size}.get(config.kind, 1)


def initial_carry(config: NetworkConfig, batch: int) -> tuple[Array, Array]:
    """Zero recurrent state for ``batch`` robots (a 1-wide dummy for MLPs)."""
    size = carry_size(config)
    zeros = jnp.zeros((batch, size), jnp.float32)
    return zeros, zeros


# ----------------------------------------------------------------------------- distributions
def log_prob(out: Array, log_std: Array | None, action: Array, discrete: bool) -> Array:
    """Log-probability of ``action`` under the head's output (``[...]``)."""
    if discrete:
        logp = jax.nn.log_softmax(out)
        return jnp.take_along_axis(logp, action[..., None].astype(jnp.int32), axis=-1)[..., 0]
    var = jnp.exp(2.0 * log_std)
    return jnp.sum(-0.5 * jnp.square(action - out) / var - log_std
                   - 0.5 * jnp.log(2.0 * jnp.pi), axis=-1)


def entropy(out: Array, log_std: Array | None, discrete: bool) -> Array:
    if discrete:
        logp = jax.nn.log_softmax(out)
        return -jnp.sum(jnp.exp(logp) * logp, axis=-1)
    return jnp.broadcast_to(jnp.sum(0.5 + 0.5 * jnp.log(2.0 * jnp.pi) + log_std),
                            out.shape[:-1])


def sample(key: Array, out: Array, log_std: Array | None, discrete: bool) -> Array:
    if discrete:
        return jax.random.categorical(key, out).astype(jnp.int32)
    return out + jnp.exp(log_std) * jax.random.normal(key, out.shape)


def greedy(out: Array, discrete: bool) -> Array:
    """The most likely action (evaluation)."""
    return jnp.argmax(out, axis=-1).astype(jnp.int32) if discrete else out
