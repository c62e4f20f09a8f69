"""Held-out worlds: every world has a seed (world ``i`` is built from ``world_key(i)``, whatever
draws it), a split is a range of seeds, and a world's identity is a hash of its quantised
parameter values, so a training run can refuse the worlds of a held-out split even when it
draws from the same ranges (``make(..., world_holdout=(first, count))``), and an evaluation
can play exactly a split's worlds (``make(..., world_seeds=(first, count))``)."""

from __future__ import annotations

from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from sgjax.maps.generated.family import Family, range_arrays, world_values
from sgjax.maps.sampling import mix32

WORLD_ROOT = 0x5EED  # the root key every world seed folds into
QUANTUM = 0.05  # parameter values are quantised to this (m, or a fraction) before hashing
TEST_SEEDS = (1 << 30, 1000)  # a held-out split far from the seeds training draws


def world_key(seed: Array | int) -> Array:
    """The key world ``seed`` is built from."""
    return jax.random.fold_in(jax.random.key(WORLD_ROOT), seed)


def values_hash(values: Mapping[str, Array]) -> Array:
    """A uint32 identity of a world's parameter values: each value (in name order) rounded to
    :data:`QUANTUM`, folded into a MurmurHash3 chain. Worlds whose every parameter rounds alike
    share it (a duplicate, whatever their spawn jitter)."""
    h = jnp.uint32(0x9E3779B9)
    for name in sorted(values):
        q = jnp.round(values[name] / QUANTUM).astype(jnp.int32).astype(jnp.uint32)
        h = mix32(h ^ (q + jnp.uint32(0x7F4A7C15) + (h << 6) + (h >> 2)))
    return h


def seed_values(family: Family, ranges: Mapping[str, tuple[float, float]], seed: Array
                ) -> dict[str, Array]:
    """The parameter values of world ``seed`` (as :func:`~sgjax.maps.generated.family.generate`
    draws them from ``world_key(seed)``)."""
    return world_values(world_key(seed), range_arrays(ranges))


def split_hashes(family: Family, ranges: Mapping[str, tuple[float, float]], first: int,
                 count: int) -> np.ndarray:
    """The sorted, distinct hashes (uint32) of the worlds with seeds ``first ... first + count
    - 1`` under ``ranges`` (kept per family, ranges and split: a second ``make`` of the same
    family in a process does not compute them again)."""
    key = (family.name, tuple(sorted((name, float(lo), float(hi))
                                     for name, (lo, hi) in ranges.items())), first, count)
    if key not in _SPLIT_HASHES:
        seeds = jnp.arange(count, dtype=jnp.uint32) + jnp.uint32(first)
        hashes = jax.jit(jax.vmap(lambda s: values_hash(seed_values(family, ranges, s))))(seeds)
        _SPLIT_HASHES[key] = np.unique(np.asarray(hashes))
    return _SPLIT_HASHES[key].copy()


# (family name, ranges, first, count) -> the split's hashes: computed once per process
_SPLIT_HASHES: dict[tuple, np.ndarray] = {}


def is_excluded(hashed: Array, excluded: Array) -> Array:
    """Whether ``hashed`` (uint32) is one of the sorted ``excluded [K]`` (a binary search)."""
    if excluded.shape[0] == 0:
        return jnp.asarray(False)
    at = jnp.clip(jnp.searchsorted(excluded, hashed), 0, excluded.shape[0] - 1)
    return excluded[at] == hashed
