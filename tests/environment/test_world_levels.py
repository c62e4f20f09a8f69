"""``world_levels``: a trainer picks each episode's generated world. Every world is then a seed
and parameter values (``WorldDraw.seed``), a reset plays the level ``EnvState.next_level``
holds when it is chosen (the seed's own world, or one with edited values) and a fresh seed
otherwise, the choice is used once, and ``step_batch`` equals ``vmap(step)`` with levels too."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.environment.worlds import Level

COUNT = 4  # environments of a batch in the tests that step one (one compiled step for them)


@pytest.fixture(scope="module")
def doorway():
    """Generated doorways chosen by levels (2 robots), with ``vmap(reset)`` and ``step_batch``
    of ``COUNT`` environments (every robot GO) jitted once for the module."""
    env, params = sgjax.make("generated:doorway", num_agents=2, time_limit=3.0, world_levels=True)
    reset = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))
    step = jax.jit(lambda keys, states: env.step_batch(
        keys, states, jnp.ones((COUNT, env.max_agents), jnp.int32), params))
    return env, params, reset, step


def _same(a, b, tolerance=0.0):
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_allclose(np.asarray(x, np.float64), np.asarray(y, np.float64),
                                   atol=tolerance, rtol=0)


def _level(values: dict, seed: int, chosen: bool, count: int, pedestrians: int = -1) -> Level:
    level = Level(seed=jnp.uint32(seed), values=values, chosen=jnp.asarray(chosen),
                  pedestrians=jnp.int32(pedestrians))
    return jax.tree.map(lambda x: jnp.broadcast_to(x, (count,) + jnp.shape(x)), level)


def test_a_fresh_world_is_its_seeds_world_and_the_reset_key_fixes_it(doorway):
    env, params, reset, _ = doorway
    source = env.config.world
    keys = jax.random.split(jax.random.key(3), 16)
    _, states = reset(keys, params)
    _, again = reset(keys, params)
    _same(states, again)
    seeds = np.asarray(states.world.seed)
    assert len(set(seeds.tolist())) == 16
    assert not np.asarray(states.next_level.chosen).any()  # nothing chosen yet
    for i in (0, 7, 15):
        own = source.of_seed(int(seeds[i]))  # eager: the same world up to float rounding
        _same(own.map, jax.tree.map(lambda x, i=i: x[i], states.world.map), 1e-5)
        _same(own.values, {k: v[i] for k, v in states.world.values.items()})


@pytest.mark.slow
def test_an_ended_episode_plays_the_chosen_level_once_then_fresh_worlds(doorway):
    env, params, reset, step = doorway
    source = env.config.world
    count = COUNT
    edited = dict(source.of_seed(41).values)
    edited["door_width"] = jnp.float32(1.55)  # an ACCEL-style edit of world 41
    _, states = reset(jax.random.split(jax.random.key(4), count), params)
    chosen = jnp.asarray([True, True, False, True])
    level = _level(edited, 41, True, count).replace(chosen=chosen)
    states = states.replace(next_level=level)
    episodes = np.zeros(count, int)
    for t in range(80):
        _, states, _, _, _, info = step(jax.random.split(jax.random.key(500 + t), count), states)
        done = np.asarray(info["episode_done"])
        seeds = np.asarray(states.world.seed)
        for i in np.flatnonzero(done):
            episodes[i] += 1
            if episodes[i] == 1 and bool(chosen[i]):
                assert seeds[i] == 41
                assert float(states.world.values["door_width"][i]) == pytest.approx(1.55)
                built = source.built(jnp.uint32(41), edited)[1]
                _same(built.map, jax.tree.map(lambda x, i=i: x[i], states.world.map), 1e-5)
            else:  # the choice was used: a fresh seed
                assert seeds[i] != 41
        assert not np.asarray(states.next_level.chosen)[done].any()
    assert (episodes >= 2).all()


@pytest.mark.slow
def test_vmap_of_step_equals_step_batch_with_chosen_levels(doorway):
    env, params, reset, batched = doorway  # batched: step_batch, every robot GO
    count = COUNT
    _, states = reset(jax.random.split(jax.random.key(5), count), params)
    values = env.config.world.of_seed(9).values
    states = states.replace(next_level=_level(values, 9, True, count).replace(
        chosen=jnp.asarray([True, False, True, False])))
    looped = jax.jit(jax.vmap(lambda k, s: env.step(k, s, jnp.ones(env.max_agents, jnp.int32),
                                                    params)))
    one, two = states, states
    for t in range(35):
        keys = jax.random.split(jax.random.key(300 + t), count)
        out_one, out_two = batched(keys, one), looped(keys, two)
        _same(out_one, out_two)
        one, two = out_one[1], out_two[1]
    assert (np.asarray(one.world.seed)[[0, 2]] == 9).all()


def test_a_level_with_held_out_values_is_not_valid():
    env, _ = sgjax.make("generated:doorway", num_agents=2, world_levels=True,
                        world_holdout=[1000, 4])
    source = env.config.world
    held = source.of_seed(1001)
    assert not bool(held.valid)  # a held-out world's values, whatever the seed
    assert not bool(source.built(jnp.uint32(7), held.values)[1].valid)
    assert bool(source.built(jnp.uint32(7), source.of_seed(7).values)[1].valid)


def test_a_splits_worlds_carry_their_seed_and_levels_refuse_a_split():
    env, params = sgjax.make("generated:doorway", num_agents=2, world_seeds=[1000, 50])
    _, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(
        jax.random.split(jax.random.key(0), 8), params)
    source = env.config.world
    for seed, width in zip(np.asarray(states.world.seed),
                           np.asarray(states.world.values["door_width"]), strict=True):
        assert 1000 <= seed < 1050
        assert float(source.of_seed(int(seed)).values["door_width"]) == pytest.approx(width)
    with pytest.raises(ValueError, match="world_levels .* and world_seeds .* exclude"):
        sgjax.make("generated:doorway", world_levels=True, world_seeds=[0, 10])


def test_a_chosen_level_that_fails_the_checks_falls_back_to_a_fresh_world():
    env, _ = sgjax.make("generated:doorway", num_agents=2, world_levels=True,
                        world_proposals=2)
    source = env.config.world
    narrow = dict(source.of_seed(5).values)
    narrow["door_width"] = jnp.float32(0.3)  # narrower than any robot: fails the checks
    assert not bool(source.built(jnp.uint32(5), narrow)[1].valid)
    level = Level(seed=jnp.uint32(5), values=narrow, chosen=jnp.asarray(True),
                  pedestrians=jnp.int32(3))
    draw = jax.jit(source.level_draw)(jax.random.key(1), level)
    assert bool(draw.valid) and int(draw.seed) != 5
    assert int(draw.pedestrians) == -1  # the fresh fallback has the environment's pedestrians
    good = level.replace(values=source.of_seed(5).values)
    played = jax.jit(source.level_draw)(jax.random.key(1), good)
    assert int(played.seed) == 5 and int(played.pedestrians) == 3


@pytest.mark.slow
def test_a_chosen_levels_pedestrians_walk_in_its_episode_and_fresh_worlds_have_the_params():
    """A level's pedestrian count (an ACCEL edit's added group) is the active pedestrians of
    its episode, read by every step from its world; a fresh world keeps the params' count."""
    env, params = sgjax.make("generated:doorway", num_agents=2, num_humans=2, max_humans=6,
                             time_limit=1.0, world_levels=True)
    count = 3
    _, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(
        jax.random.split(jax.random.key(2), count), params)
    assert (np.asarray(states.humans.active).sum(axis=1) == 2).all()
    level = _level(env.config.world.of_seed(9).values, 9, True, count).replace(
        chosen=jnp.asarray([True, False, True]), pedestrians=jnp.asarray([5, 5, 0], jnp.int32))
    states = states.replace(next_level=level)

    @jax.jit
    def step(keys, states):  # and the pedestrian count of each episode's params
        out = env.step_batch(keys, states, jnp.ones((count, env.max_agents), jnp.int32), params)
        return out, jax.vmap(env.params_in, in_axes=(0, None))(out[1], params).humans.num_humans

    first = np.zeros(count, bool)
    for t in range(12):
        (_, states, _, _, _, info), humans = step(
            jax.random.split(jax.random.key(50 + t), count), states)
        ended = np.asarray(info["episode_done"]) & ~first
        first |= ended
        active = np.asarray(states.humans.active).sum(axis=1)
        for i in np.flatnonzero(ended):
            want = [5, 2, 0][i]
            assert active[i] == want and int(humans[i]) == want
            assert int(states.world.pedestrians[i]) == [5, -1, 0][i]
    assert first.all()
