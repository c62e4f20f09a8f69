"""Reward terms and the Rewarder that sums them with (scheduled) weights.

A reward term (:class:`RewardTerm`) is called with the one term input,
``term(inputs: TermInput) -> [R]``: its raw value per robot for the step from ``inputs.prev`` to
``inputs.state``, with its natural sign (penalties are negative), so every weight is a positive
scale. Weights are :class:`~sgjax.rewards.schedules.Schedule` pytrees in
``params.reward.weights[name]``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import jax.numpy as jnp
from jax import Array

from sgjax.rewards.schedules import Schedule, parse_schedule
from sgjax.terms.base import Registry, TermSet, parse_terms
from sgjax.terms.contract import Term, TermInput
from sgjax.types import RewardParams


@dataclasses.dataclass(frozen=True)
class RewardTerm(Term):
    """Base class of reward terms: subclasses set ``name`` and implement
    ``__call__(inputs) -> [R]`` (float, natural sign, per robot for the step from
    ``inputs.prev`` to ``inputs.state``). The Rewarder weights it and zeroes robots that were
    not active at ``inputs.prev``."""

    def __call__(self, inputs: TermInput) -> Array:
        raise NotImplementedError


REWARDS = Registry("reward term", RewardTerm)


def _weight_and_options(where: str, entry: Any) -> tuple[Any, Any]:
    """A reward entry: a weight (a number or a schedule mapping), or a mapping of options with
    an optional ``weight`` (default 1). Returns ``(options, weight)``."""
    if isinstance(entry, Mapping) and "schedule" not in entry:
        return {k: v for k, v in entry.items() if k != "weight"}, entry.get("weight", 1.0)
    return {}, entry


@dataclasses.dataclass(frozen=True)
class Rewarder(TermSet):
    """Terms with distinct names; ``reward = sum_i weight_i(t) * term_i``."""

    terms: tuple[RewardTerm, ...]
    section = "rewards"

    @classmethod
    def parse(cls, spec: Any, where: str = "rewards") -> tuple[Rewarder, RewardParams]:
        """From a mapping ``{term: weight}`` or ``{term: {weight: w, option: value, ...}}``,
        where a weight is a number or a schedule mapping (see ``parse_schedule``); the weight
        defaults to 1. Returns the Rewarder and its weights (``params.reward``)."""
        parsed = parse_terms(spec, REWARDS, where, lists=False, entry=_weight_and_options)
        weights: dict[str, Schedule] = {
            term.name: parse_schedule(f"{where}.{term.name}.weight", weight)
            for term, weight in parsed}
        return cls(tuple(term for term, _ in parsed)), RewardParams(weights=weights)

    def check_params(self, reward: RewardParams) -> None:
        """Raise if ``params.reward`` does not carry exactly one weight per term."""
        if set(reward.weights) != set(self.names):
            raise ValueError(f"params.reward.weights: expected weights for {sorted(self.names)},"
                             f" got {sorted(reward.weights)}")

    def __call__(self, inputs: TermInput) -> tuple[Array, dict[str, Array]]:
        """``(reward [R], weighted value of each term {name: [R]})``, zero for robots that were
        not active at ``inputs.prev``; weights are read at ``prev.total_steps``."""
        prev, params = inputs.prev, inputs.params
        was_active = prev.robots.active
        parts = {}
        for term, term_inputs in self.each(inputs):
            weight = params.reward.weights[term.name](prev.total_steps)
            value = term(term_inputs)
            parts[term.name] = jnp.where(was_active, weight * value, 0.0)
        total = sum(parts.values(), jnp.zeros(inputs.layout.max_agents, jnp.float32))
        return total, parts
