"""Every registered observation term, reward term and ender meets the one term contract.

Parametrised over the three registries, so a term is tested the day it is registered: with its
default options, inside one environment that has every term at once (one compile), with
pedestrians, conflict zones and absent robot slots, over a random GO/STOP rollout. Every term
is called the same way, ``term(inputs)``, with the same :class:`~sgjax.terms.contract.TermInput`
(a step from the middle of the rollout), and returns its own kind of output:

* observation terms: ``[R, size]`` float (or bool), finite; the published column layout has
  ``size`` uniquely named columns; zero rows for absent robots in the observation;
* reward terms: ``[R]`` float, finite; zero for absent robots in ``info["reward_terms"]``;
* enders: an ``Outcome`` of ``[R]`` bool / bool / float, finite, never ending an absent robot.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.observations import OBSERVATIONS, ObservationTerm
from sgjax.rewards import REWARDS, RewardTerm
from sgjax.terms.contract import Term, TermInput
from sgjax.terms.enders import ENDERS, Ender, Outcome

PRESENT, SLOTS, STEPS = 2, 4, 60
KINDS = {"observation": OBSERVATIONS, "reward": REWARDS, "ender": ENDERS}
EVERY_TERM = [(kind, name) for kind, registry in KINDS.items() for name in registry.names()]


@functools.cache
def world():
    """An intersection with every term, 2 of 4 robot slots present and 3 pedestrians, and a
    60-step rollout: ``(env, params, states [T], actions [T, R], obs [T, R, D],
    reward_terms {name: [T, R]}, terminated [T, R], truncated [T, R])``."""
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
        return next_state, (state, actions, obs, info["reward_terms"], terminated, truncated)

    _, trace = jax.jit(lambda s: jax.lax.scan(body, s, jax.random.split(jax.random.key(1),
                                                                         STEPS)))(state)
    return (env, params) + trace


@functools.cache
def step_input() -> TermInput:
    """The one input every term is called with: the step from the rollout's middle."""
    env, params, states, actions, *_ = world()
    at = lambda t: jax.tree.map(lambda x: x[t], states)  # noqa: E731
    return TermInput(prev=at(STEPS // 2), state=at(STEPS // 2 + 1),
                     actions=actions[STEPS // 2], params=params, key=jax.random.key(2),
                     layout=env.config.layout)


def absent() -> np.ndarray:
    return np.arange(SLOTS) >= PRESENT


def configured(kind: str, name: str) -> Term:
    env = world()[0]
    terms = {"observation": env.config.observer, "reward": env.config.rewarder,
             "ender": env.config.enders}[kind]
    return terms.terms[terms.names.index(name)]


@pytest.mark.parametrize(("kind", "name"), EVERY_TERM)
def test_term_takes_the_one_input(kind, name):
    """Every kind subclasses Term under its kind's base, and is called as ``term(inputs)``."""
    term = configured(kind, name)
    base = {"observation": ObservationTerm, "reward": RewardTerm, "ender": Ender}[kind]
    assert isinstance(term, base) and isinstance(term, Term) and term.name == name
    assert KINDS[kind].classes[name] is type(term)
    out = term(step_input())
    leaves = jax.tree.leaves(out)
    assert leaves and all(np.isfinite(np.asarray(v, np.float32)).all() for v in leaves)


@pytest.mark.parametrize("name", OBSERVATIONS.names())
def test_observation_term(name):
    env, params, states, _, obs, *_ = world()
    layout = env.config.layout
    term = configured("observation", name)
    value = term(step_input())
    assert value.shape == (SLOTS, term.size(layout))
    assert jnp.issubdtype(value.dtype, jnp.floating) or value.dtype == bool
    columns = term.columns(layout)
    assert len(columns) == columns.repeat * columns.width == term.size(layout)
    assert len(set(columns.names)) == len(columns.names) == term.size(layout)
    assert columns.width == 0 or columns.feature_names  # every column belongs to a feature
    # The same state observed alone gives the same value (observations read one state).
    alone = term(TermInput.observing(step_input().state, params, layout, jax.random.key(2)))
    np.testing.assert_array_equal(np.asarray(alone), np.asarray(value))
    part = np.asarray(env.split_observation(obs)[name])
    assert part.shape == (STEPS, SLOTS, term.size(layout)) and part.dtype == np.float32
    assert np.isfinite(part).all()
    assert (part[:, absent()] == 0).all()
    assert env.config.observer.columns(layout).span(name) == env.observation_slices()[name]


@pytest.mark.parametrize("name", REWARDS.names())
def test_reward_term(name):
    *_, reward_terms, _, _ = world()
    value = configured("reward", name)(step_input())
    assert value.shape == (SLOTS,) and jnp.issubdtype(value.dtype, jnp.floating)
    weighted = np.asarray(reward_terms[name])
    assert weighted.shape == (STEPS, SLOTS) and np.isfinite(weighted).all()
    assert (weighted[:, absent()] == 0).all()


@pytest.mark.parametrize("name", ENDERS.names())
def test_ender(name):
    *_, terminated, truncated = world()
    out = configured("ender", name)(step_input())
    assert isinstance(out, Outcome)
    for field, kind in (("terminated", bool), ("truncated", bool), ("reward", np.floating)):
        value = np.asarray(getattr(out, field))
        assert value.shape == (SLOTS,) and np.issubdtype(value.dtype, kind), field
    assert not np.asarray(terminated)[:, absent()].any()
    assert not np.asarray(truncated)[:, absent()].any()
