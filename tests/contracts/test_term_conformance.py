"""Every registered observation term, reward term and ender meets the term contract.

Parametrised over the registries, so a term is tested the day it is registered: with its
default options, inside one environment that has every term at once (one compile), with
pedestrians, conflict zones and absent robot slots, over a random GO/STOP rollout:

* observation terms: ``[R, size]`` float32, finite, zero rows for absent robots;
* reward terms: ``[R]`` float, finite, zero for absent robots in ``info["reward_terms"]``;
* enders: ``Outcome`` of ``[R]`` bool / float, finite, never ending an absent robot.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.observations import OBSERVATIONS
from sgjax.rewards import REWARDS
from sgjax.terms.enders import ENDERS

PRESENT, SLOTS, STEPS = 2, 4, 60


@functools.cache
def world():
    """An intersection with every term, 2 of 4 robot slots present and 3 pedestrians, and a
    60-step rollout: ``(env, params, states [T], obs [T, R, D], reward_terms {name: [T, R]},
    terminated [T, R], truncated [T, R])``."""
    env, params = sgjax.make(
        "intersection", num_agents=PRESENT, max_agents=SLOTS, num_humans=3,
        observations=OBSERVATIONS.names(), rewards={name: 1.0 for name in REWARDS.names()},
        enders=ENDERS.names())
    _, state = env.reset(jax.random.key(0), params)

    def body(state, key):
        k_act, k_step = jax.random.split(key)
        actions = jax.random.bernoulli(k_act, 0.2, (SLOTS,)).astype(jnp.int32)
        obs, next_state, _, terminated, truncated, info = env.step_env(k_step, state, actions,
                                                                        params)
        return next_state, (state, obs, info["reward_terms"], terminated, truncated)

    _, trace = jax.jit(lambda s: jax.lax.scan(body, s, jax.random.split(jax.random.key(1),
                                                                         STEPS)))(state)
    return (env, params) + trace


def absent() -> np.ndarray:
    return np.arange(SLOTS) >= PRESENT


@pytest.mark.parametrize("name", OBSERVATIONS.names())
def test_observation_term(name):
    env, params, states, obs, *_ = world()
    layout = env.config.layout
    term = env.config.observer.terms[env.config.observer.names.index(name)]
    state = jax.tree.map(lambda x: x[STEPS // 2], states)
    value = term(state, params, layout, jax.random.key(2))
    assert value.shape == (SLOTS, term.size(layout))
    assert jnp.issubdtype(value.dtype, jnp.floating) or value.dtype == bool
    assert np.isfinite(np.asarray(value, np.float32)).all()
    part = np.asarray(env.split_observation(obs)[name])
    assert part.shape == (STEPS, SLOTS, term.size(layout)) and part.dtype == np.float32
    assert np.isfinite(part).all()
    assert (part[:, absent()] == 0).all()


@pytest.mark.parametrize("name", REWARDS.names())
def test_reward_term(name):
    env, params, states, _, reward_terms, *_ = world()
    term = env.config.rewarder.terms[env.config.rewarder.names.index(name)]
    prev = jax.tree.map(lambda x: x[STEPS // 2], states)
    state = jax.tree.map(lambda x: x[STEPS // 2 + 1], states)
    value = term(prev, state, jnp.zeros(SLOTS, jnp.int32), params, env.config.layout)
    assert value.shape == (SLOTS,) and jnp.issubdtype(value.dtype, jnp.floating)
    assert np.isfinite(np.asarray(value)).all()
    weighted = np.asarray(reward_terms[name])
    assert weighted.shape == (STEPS, SLOTS) and np.isfinite(weighted).all()
    assert (weighted[:, absent()] == 0).all()


@pytest.mark.parametrize("name", ENDERS.names())
def test_ender(name):
    env, params, states, _, _, terminated, truncated = world()
    ender = env.config.enders.terms[env.config.enders.names.index(name)]
    prev = jax.tree.map(lambda x: x[STEPS // 2], states)
    state = jax.tree.map(lambda x: x[STEPS // 2 + 1], states)
    out = ender(prev, state, params, env.config.layout)
    for field, kind in (("terminated", bool), ("truncated", bool), ("reward", np.floating)):
        value = np.asarray(getattr(out, field))
        assert value.shape == (SLOTS,) and np.issubdtype(value.dtype, kind), field
    assert np.isfinite(np.asarray(out.reward)).all()
    assert not np.asarray(terminated)[:, absent()].any()
    assert not np.asarray(truncated)[:, absent()].any()
