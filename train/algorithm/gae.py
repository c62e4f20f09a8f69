"""Generalised advantage estimation over one rollout, as a pure function."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from jax import Array

from train.algorithm.state import Transition


def gae(traj: Transition, last_value: Array, gamma: Any, gamma_lambda: Any
        ) -> tuple[Array, Array]:
    """Advantages and value targets ``[T, B]`` of ``traj [T, B, ...]``, bootstrapped from
    ``last_value [B]`` (the critic's value after the last step). A truncated robot's step
    bootstraps from its final observation's value (``final_value``), a terminated one's from
    nothing; ``gamma`` and ``gamma_lambda`` (``gamma x lambda``) are numbers or float32
    scalars (a lane's)."""

    def back(carry, t):
        advantage, next_value = carry
        bootstrap = jnp.where(t.truncated, t.final_value, next_value)
        delta = t.reward + gamma * bootstrap * (1.0 - t.terminated) - t.value
        done = (t.terminated | t.truncated).astype(jnp.float32)
        advantage = delta + gamma_lambda * (1.0 - done) * advantage
        return (advantage, t.value), advantage

    _, advantages = jax.lax.scan(back, (jnp.zeros_like(last_value), last_value), traj,
                                 reverse=True)
    return advantages, advantages + traj.value
