"""Reward terms and the Rewarder that sums them with (scheduled) weights.

A term is a frozen dataclass (its fields are its options) with a ``name`` and a call
``term(prev, state, actions, params, layout) -> [R]``: its raw value per robot for the step from
``prev`` to ``state``, with its natural sign (penalties are negative), so every weight is a
positive scale. Weights are :class:`~sgjax.rewards.schedules.Schedule` pytrees in
``params.reward.weights[name]``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar

import jax.numpy as jnp
from jax import Array

from sgjax.rewards.schedules import parse_schedule
from sgjax.terms.base import ConfigError, Registry, TermSet
from sgjax.types import RewardParams

if TYPE_CHECKING:
    from sgjax.types import EnvParams, EnvState, Layout

REWARDS = Registry("reward term")


@dataclasses.dataclass(frozen=True)
class RewardTerm:
    """Base class: subclasses set ``name`` and implement ``__call__``."""

    name: ClassVar[str] = ""
    uses_zones: ClassVar[bool] = False  # reads state.zones (conflict-zone bookkeeping)

    def __call__(self, prev: EnvState, state: EnvState, actions: Array, params: EnvParams,
                 layout: Layout) -> Array:
        raise NotImplementedError


@dataclasses.dataclass(frozen=True)
class Rewarder(TermSet):
    """Terms with distinct names; ``reward = sum_i weight_i(t) * term_i``."""

    terms: tuple[RewardTerm, ...]
    section = "rewards"

    def check_params(self, reward: RewardParams) -> None:
        """Raise if ``params.reward`` does not carry exactly one weight per term."""
        if set(reward.weights) != set(self.names):
            raise ValueError(f"params.reward.weights: expected weights for {sorted(self.names)},"
                             f" got {sorted(reward.weights)}")

    def __call__(self, prev: EnvState, state: EnvState, actions: Array, params: EnvParams,
                 layout: Layout) -> tuple[Array, dict[str, Array]]:
        """``(reward [R], weighted value of each term {name: [R]})``, zero for robots that were
        not was_active at ``prev``; weights are read at ``prev.total_steps``."""
        was_active = prev.robots.active
        parts = {}
        for term in self.terms:
            weight = params.reward.weights[term.name](prev.total_steps)
            value = term(prev, state, actions, params, layout)
            parts[term.name] = jnp.where(was_active, weight * value, 0.0)
        total = sum(parts.values(), jnp.zeros(layout.max_agents, jnp.float32))
        return total, parts


def parse_rewards(spec: Any, where: str = "rewards") -> tuple[Rewarder, RewardParams]:
    """From a mapping ``{term: weight}`` or ``{term: {weight: w, option: value, ...}}``, where a
    weight is a number or a schedule mapping (see ``parse_schedule``); the weight defaults to 1."""
    if not isinstance(spec, Mapping):
        raise ConfigError(f"{where}: expected a mapping of reward terms to weights, got {spec!r}"
                          f"; valid terms are: {', '.join(REWARDS.names())}")
    terms, weights = [], {}
    for name, entry in spec.items():
        if isinstance(entry, Mapping) and "schedule" not in entry:
            options = {k: v for k, v in entry.items() if k != "weight"}
            weight = entry.get("weight", 1.0)
        else:
            options, weight = {}, entry
        term = REWARDS.build(where, name, options)
        terms.append(term)
        weights[term.name] = parse_schedule(f"{where}.{name}.weight", weight)
    return Rewarder(tuple(terms)), RewardParams(weights=weights)
