"""A family of generated worlds: its parameters with their default ranges and hard limits, its
static capacity, and its ``build`` (parameter values and a key -> :class:`World`).

A world is drawn in two steps: :func:`draw_values` draws every parameter uniformly from its
range (the ranges are arrays, so a curriculum may move them per lane), then the family builds
the world from the values (an ACCEL-style mutation edits the values and builds again)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

import jax
import jax.numpy as jnp
from jax import Array

from sgjax.maps.generated.world import Capacity, World
from sgjax.validation import suggest


@dataclasses.dataclass(frozen=True)
class Parameter:
    """One parameter of a family: its default range ``(low, high)`` and the hard limits any
    range must stay within (what the family's capacity and geometry allow), with its unit."""

    default: tuple[float, float]
    limits: tuple[float, float]
    unit: str
    doc: str


@dataclasses.dataclass(frozen=True)
class Family:
    """A generator of worlds (see the module doc)."""

    name: str
    description: str
    parameters: Mapping[str, Parameter]
    capacity: Capacity
    build: Callable[[Mapping[str, Array], Array], World]
    # the family's own shortest routes, ``(gap, adjacency, edges) -> (dist, next_hop, hops,
    # fits)`` (:func:`sgjax.maps.generated.compiled.world_arrays`); None: Floyd-Warshall over
    # the capacity's hubs, the routes walked to count their hops
    routes: Callable[[Array, Array, Array], tuple[Array, Array, Array, Array]] | None = None

    def ranges(self, overrides: Mapping[str, Any] | None = None) -> dict[str, tuple[float, float]]:
        """The default ranges with ``overrides`` ({name: (low, high) or a number}) on top,
        checked: a ValueError names an unknown parameter or a range outside its limits."""
        ranges = {name: p.default for name, p in self.parameters.items()}
        for name, value in (overrides or {}).items():
            if name not in self.parameters:
                raise ValueError(f"world family {self.name!r}: no parameter {name!r}"
                                 f"{suggest(name, list(self.parameters))}; it has "
                                 f"{', '.join(self.parameters)}")
            low, high = (value, value) if isinstance(value, int | float) else value
            low, high = float(low), float(high)
            lo, hi = self.parameters[name].limits
            if not lo <= low <= high <= hi:
                raise ValueError(f"world family {self.name!r}: {name} range [{low:g}, "
                                 f"{high:g}] must lie within [{lo:g}, {hi:g}] "
                                 f"{self.parameters[name].unit} with low <= high")
            ranges[name] = (low, high)
        return ranges


def range_arrays(ranges: Mapping[str, tuple[float, float]]) -> dict[str, Array]:
    """``{name: [2] float32}``: ranges as arrays (traced in ``jit``)."""
    return {name: jnp.asarray(pair, jnp.float32) for name, pair in ranges.items()}


def draw_values(key: Array, ranges: Mapping[str, Array]) -> dict[str, Array]:
    """Every parameter drawn uniformly from its range ``[2]``, one key per parameter (in
    name order, so adding a parameter does not change the others' draws)."""
    names = sorted(ranges)
    keys = jax.random.split(key, len(names))
    return {name: jax.random.uniform(k, (), jnp.float32, ranges[name][0], ranges[name][1])
            for name, k in zip(names, keys, strict=True)}


def world_values(key: Array, ranges: Mapping[str, Array]) -> dict[str, Array]:
    """The parameter values :func:`generate` draws from ``key`` (without building the
    world)."""
    return draw_values(jax.random.split(key)[0], ranges)


def generate(family: Family, key: Array, ranges: Mapping[str, Array]) -> tuple[World, dict]:
    """A world of ``family`` from ``key``: ``(world, the drawn values)``; the same key and
    ranges give the same world."""
    values = world_values(key, ranges)
    return family.build(values, jax.random.split(key)[1]), values
