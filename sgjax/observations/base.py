"""Observation terms and the Observer that concatenates them.

A term is a frozen dataclass (its fields are its options) with a ``name``, a ``size`` and a
call ``term(state, params, layout, key) -> [R, size]`` for one episode's robots. The Observer
stacks its terms into ``obs [R, D]`` in order and knows which slice belongs to which term.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

import jax
import jax.numpy as jnp
from jax import Array

from sgjax.terms.base import ConfigError, Registry, TermSet

if TYPE_CHECKING:
    from sgjax.types import EnvParams, EnvState, Layout

OBSERVATIONS = Registry("observation term")


@dataclasses.dataclass(frozen=True)
class ObservationTerm:
    """Base class: subclasses set ``name`` and implement ``size`` and ``__call__``."""

    name: ClassVar[str] = ""
    history: ClassVar[int] = 1  # steps of history the term reads (instances may override)
    needs_key: ClassVar[bool] = False
    uses_zones: ClassVar[bool] = False  # reads state.zones (conflict-zone bookkeeping)

    def size(self, layout: Layout) -> int:
        raise NotImplementedError

    def __call__(self, state: EnvState, params: EnvParams, layout: Layout, key: Array
                 ) -> Array:
        raise NotImplementedError


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

    @property
    def needs_key(self) -> bool:
        """Whether any term draws random numbers (observation noise)."""
        return any(t.needs_key for t in self.terms)

    @property
    def history_length(self) -> int:
        """Steps of state history the terms need (at least 1: the current step)."""
        return max([1] + [int(t.history) for t in self.terms])

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
        """One line per term: ``name [start:stop] size``."""
        return "\n".join(f"{name:<24} [{s.start}:{s.stop}] size {s.stop - s.start}"
                         for name, s in self.slices(layout).items())

    def split(self, obs: Array, layout: Layout) -> dict[str, Array]:
        """Cut observations ``[..., D]`` into a dict of ``[..., size]`` by term name."""
        return {name: obs[..., s] for name, s in self.slices(layout).items()}

    def __call__(self, state: EnvState, params: EnvParams, layout: Layout, key: Array
                 ) -> Array:
        """``obs [R, D]`` (float32); rows of robots not in the episode are zeros."""
        keys = (jax.random.split(key, len(self.terms)) if self.needs_key
                else [key] * len(self.terms))
        parts = []
        for term, term_key in zip(self.terms, keys, strict=True):
            value = term(state, params, layout, term_key)
            expected = (layout.max_agents, term.size(layout))
            if value.shape != expected:
                raise RuntimeError(f"observation term {term.name!r} returned shape "
                                   f"{value.shape}, expected {expected}")
            parts.append(value.astype(jnp.float32))
        obs = jnp.concatenate(parts, axis=-1)
        return jnp.where(state.robots.present[:, None], obs, 0.0)


def parse_observations(spec: Any, where: str = "observations") -> Observer:
    """Build an :class:`Observer` from a list whose items are a term name or a one-key mapping
    ``{name: {option: value}}``; a mapping ``{name: options}`` is taken in its order."""
    if isinstance(spec, Observer):
        return spec
    if isinstance(spec, Mapping):
        items: Sequence[Any] = [{k: v} for k, v in spec.items()]
    elif isinstance(spec, Sequence) and not isinstance(spec, str):
        items = spec
    else:
        raise ConfigError(f"{where}: expected a list of terms, got {spec!r}")
    terms = []
    for i, item in enumerate(items):
        if isinstance(item, ObservationTerm):
            terms.append(item)
        elif isinstance(item, str):
            terms.append(OBSERVATIONS.build(f"{where}[{i}]", item, {}))
        elif isinstance(item, Mapping) and len(item) == 1:
            (name, options), = item.items()
            terms.append(OBSERVATIONS.build(f"{where}[{i}]", name, options))
        else:
            raise ConfigError(f"{where}[{i}]: expected a term name or {{name: options}}, "
                              f"got {item!r}")
    return Observer(tuple(terms))
