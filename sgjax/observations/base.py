"""Observation terms and the Observer that concatenates them.

An observation term (:class:`ObservationTerm`) is called with the one term input,
``term(inputs: TermInput) -> [R, size]``, for one episode's robots, and publishes its column
layout (``columns(layout)``: what each of its ``size(layout)`` columns holds). The Observer
stacks its terms into ``obs [R, D]`` in order and publishes the layout of the whole vector.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any, ClassVar

import jax.numpy as jnp
from jax import Array

from sgjax.observations.columns import Columns, ObservationColumns
from sgjax.terms.base import ConfigError, Registry, TermSet, parse_terms
from sgjax.terms.contract import Term, TermInput

if TYPE_CHECKING:
    from sgjax.types import Layout


@dataclasses.dataclass(frozen=True)
class ObservationTerm(Term):
    """Base class of observation terms: subclasses set ``name`` and implement ``columns`` and
    ``__call__(inputs) -> [R, size]`` (float or bool; the Observer casts to float32).

    ``columns(layout)`` names the term's columns (:class:`~sgjax.observations.columns.Columns`);
    ``size(layout)`` is their number. ``history``: steps of state history the term reads
    (``state.history`` keeps the longest any term of the environment asks for).
    """

    history: ClassVar[int] = 1  # steps of history the term reads (instances may override)

    def columns(self, layout: Layout) -> Columns:
        raise NotImplementedError

    def size(self, layout: Layout) -> int:
        """The number of columns, ``len(self.columns(layout))``."""
        return self.columns(layout).size

    def __call__(self, inputs: TermInput) -> Array:
        raise NotImplementedError


OBSERVATIONS = Registry("observation term", ObservationTerm)


@dataclasses.dataclass(frozen=True)
class Observer(TermSet):
    """An ordered tuple of observation terms with distinct names."""

    terms: tuple[ObservationTerm, ...]
    section = "observations"

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.terms:
            raise ConfigError("observations: at least one term is needed; valid terms are: "
                              + ", ".join(OBSERVATIONS.names()))

    @classmethod
    def parse(cls, spec: Any, where: str = "observations") -> Observer:
        """From a list whose items are a term name or a one-key mapping
        ``{name: {option: value}}``; a mapping ``{name: options}`` is taken in its order
        (see :func:`sgjax.terms.base.parse_terms`). An Observer is returned as it is."""
        if isinstance(spec, Observer):
            return spec
        return cls(tuple(term for term, _ in parse_terms(spec, OBSERVATIONS, where)))

    @property
    def history_length(self) -> int:
        """Steps of state history the terms need (at least 1: the current step)."""
        return max([1] + [int(t.history) for t in self.terms])

    def columns(self, layout: Layout) -> ObservationColumns:
        """The layout of the observation vector: each term's span and column names."""
        return ObservationColumns.of([(t.name, t.columns(layout)) for t in self.terms])

    def sizes(self, layout: Layout) -> dict[str, int]:
        return {t.name: int(t.size(layout)) for t in self.terms}

    def size(self, layout: Layout) -> int:
        """Length ``D`` of one robot's observation vector."""
        return sum(self.sizes(layout).values())

    def slices(self, layout: Layout) -> dict[str, slice]:
        """Which slice of the observation vector holds which term."""
        out, start = {}, 0
        for name, n in self.sizes(layout).items():
            out[name] = slice(start, start + n)
            start += n
        return out

    def describe(self, layout: Layout) -> str:
        """One line per term: ``name [start:stop] size``, its blocks and its columns."""
        return self.columns(layout).describe()

    def split(self, obs: Array, layout: Layout) -> dict[str, Array]:
        """Cut observations ``[..., D]`` into a dict of ``[..., size]`` by term name."""
        return {name: obs[..., s] for name, s in self.slices(layout).items()}

    def __call__(self, inputs: TermInput) -> Array:
        """``obs [R, D]`` (float32) of ``inputs.state``; rows of robots not in the episode are
        zeros. Terms that draw random numbers get keys split from ``inputs.key``."""
        layout = inputs.layout
        parts = []
        for term, term_inputs in self.each(inputs):
            value = term(term_inputs)
            expected = (layout.max_agents, term.size(layout))
            if value.shape != expected:
                raise RuntimeError(f"observation term {term.name!r} returned shape "
                                   f"{value.shape}, expected {expected}")
            parts.append(value.astype(jnp.float32))
        obs = jnp.concatenate(parts, axis=-1)
        return jnp.where(inputs.state.robots.present[:, None], obs, 0.0)
