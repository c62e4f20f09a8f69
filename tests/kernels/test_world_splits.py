"""Held-out splits of generated worlds (``sgjax.maps.generated.splits``): a world's seed fixes
it, its hash is that of its quantised parameters, an evaluation plays exactly a split's worlds
and a training run never draws a held-out world, even from the same ranges."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.environment.worlds import source_for
from sgjax.maps.generated.families import family
from sgjax.maps.generated.splits import (
    QUANTUM,
    is_excluded,
    seed_values,
    split_hashes,
    values_hash,
)

# every doorway parameter fixed but the door's width, over 7 quantised steps: duplicates abound
NARROW = {"room_height": 10.0, "left_depth": 8.0, "right_depth": 8.0, "wall_thickness": 0.5,
          "door_offset": 0.0, "door_width": (1.0, 1.3)}


def test_hashes_follow_the_quantised_values():
    base = {"a": jnp.float32(1.0), "b": jnp.float32(2.0)}
    assert int(values_hash(base)) == int(values_hash({"b": jnp.float32(2.0),
                                                       "a": jnp.float32(1.0)}))
    near = {"a": jnp.float32(1.0 + QUANTUM / 10), "b": jnp.float32(2.0)}
    far = {"a": jnp.float32(1.0 + 2 * QUANTUM), "b": jnp.float32(2.0)}
    assert int(values_hash(near)) == int(values_hash(base))
    assert int(values_hash(far)) != int(values_hash(base))
    hashes = jnp.asarray([3, 9, 40], jnp.uint32)
    assert [bool(is_excluded(jnp.uint32(h), hashes)) for h in (3, 4, 40, 41)] == [
        True, False, True, False]
    assert not bool(is_excluded(jnp.uint32(3), jnp.zeros(0, jnp.uint32)))


@pytest.mark.slow
def test_a_seed_fixes_its_world_and_a_split_plays_only_its_worlds():
    fam = family("doorway")
    ranges = fam.ranges()
    one = seed_values(fam, ranges, 1 << 30)
    again = seed_values(fam, ranges, 1 << 30)
    assert all(float(one[k]) == float(again[k]) for k in one)
    split = (1 << 30, 20)
    allowed = set(split_hashes(fam, ranges, *split).tolist())
    env, params = sgjax.make("generated:doorway", num_agents=2, world_seeds=split)
    _, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(
        jax.random.split(jax.random.key(5), 64), params)
    played = jax.vmap(values_hash)(states.world.values)
    assert set(np.asarray(played).tolist()) <= allowed
    assert len(set(np.asarray(played).tolist())) > 10  # many of the split's 20 worlds


def test_training_beside_a_holdout_never_draws_its_worlds():
    fam = family("doorway")
    holdout = (1 << 30, 3)
    held = split_hashes(fam, fam.ranges(NARROW), *holdout)
    assert 1 <= len(held) <= 3
    source = source_for("doorway", NARROW, holdout=holdout, check_dilemma=False)
    # one world built per reset: held-out values are redrawn before building
    assert source.proposals == 1 and set(source.exclude) == set(held.tolist())
    draws = jax.jit(jax.vmap(source.draw))(jax.random.split(jax.random.key(0), 256))
    hashes = np.asarray(jax.vmap(values_hash)(draws.values))
    valid = np.asarray(draws.valid)
    assert valid.mean() > 0.5
    assert not np.isin(hashes[valid], held).any()  # a valid world is never held out
    assert np.isin(hashes[~valid], held).all()  # and every flagged one was
    free = source_for("doorway", NARROW, check_dilemma=False)
    seen = np.asarray(jax.vmap(values_hash)(jax.jit(jax.vmap(free.draw))(
        jax.random.split(jax.random.key(0), 256)).values))
    assert np.isin(seen, held).any()  # without the holdout, the held worlds do come up


def test_bad_splits_are_refused_by_name():
    for bad in ([1], [0, 0], [-1, 5], "ab", [0.5, 3]):
        with pytest.raises(ValueError, match="world_seeds must be \\[first, count\\]"):
            sgjax.make("generated:doorway", world_seeds=bad)
    with pytest.raises(ValueError, match="world_holdout must be"):
        sgjax.make("generated:doorway", world_holdout=[1, 2, 3])
