"""Pedestrians in generated worlds: every world computes its spawn slots inside ``jit``
(:func:`sgjax.humans.slots.world_spawn_slots`), the same slots the host computes for the
exported map; pedestrians start on the episode's world's slots, walk to its nodes only, and
``step_batch`` equals ``vmap(step)`` with them."""

from __future__ import annotations

import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.environment.worlds import source_for
from sgjax.humans.pedestrians import _random_other_node
from sgjax.humans.slots import SPAWN_JITTER, spawn_slots
from sgjax.maps import parse_map
from sgjax.maps.generated.export import world_map
from sgjax.maps.generated.families import FAMILIES

RADIUS = 0.3
EXACT = os.environ.get("SGJAX_TEST_FULL_OPTIMIZATION") == "1"  # bitwise under full compiles


@pytest.mark.slow
@pytest.mark.parametrize("name", list(FAMILIES))
def test_in_jit_slots_are_the_host_slots_of_the_exported_world(name):
    source = source_for(name, human_radius=RADIUS)
    play = jax.jit(lambda s: source.chosen(None, s))
    for seed in range(4):
        world, draw = play(jnp.uint32(seed))
        slots = draw.humans
        valid = np.asarray(slots.valid)
        mine = np.stack([np.asarray(slots.x)[valid], np.asarray(slots.y)[valid]], -1)
        host, host_edges = spawn_slots(parse_map(world_map(world, "w", "", draw.values)), RADIUS)
        assert len(mine) == len(host) > 0, (name, seed)
        gap = np.linalg.norm(mine[:, None] - host[None], axis=-1)
        assert gap.min(axis=1).max() < 1e-3 and gap.min(axis=0).max() < 1e-3
        # each slot's edge is a real edge of the world
        nodes = np.asarray(slots.nodes)[valid]
        assert np.asarray(world.node_valid)[nodes].all()


@pytest.fixture(scope="module")
def crowd():
    return sgjax.make("generated:floorplan", num_agents=2, num_humans=6, time_limit=6.0)


def test_pedestrians_start_on_their_worlds_slots_and_walk_to_its_nodes(crowd):
    env, params = crowd
    keys = jax.random.split(jax.random.key(0), 6)
    _, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, params)
    humans, slots = states.humans, states.world.humans
    assert np.asarray(humans.active).all()
    for i in range(6):
        valid = np.asarray(slots.valid[i])
        px, py = np.asarray(slots.x[i])[valid], np.asarray(slots.y[i])[valid]
        for x, y in zip(np.asarray(humans.x[i]), np.asarray(humans.y[i]), strict=True):
            assert np.min(np.maximum(abs(px - x), abs(py - y))) <= SPAWN_JITTER + 1e-5
        nodes = np.asarray(slots.node_valid[i])
        assert nodes[np.asarray(humans.goal[i])].all()
        assert nodes[np.asarray(humans.target[i])].all()
    # different worlds, different slots
    assert not np.array_equal(np.asarray(slots.valid[0]), np.asarray(slots.valid[1]))


@pytest.mark.slow
def test_vmap_of_step_equals_step_batch_with_pedestrians_and_goals_stay_valid(crowd):
    env, params = crowd
    count = 3
    _, states = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(jax.random.key(1),
                                                                       count), params)
    actions = jnp.ones((count, env.max_agents), jnp.int32)
    batched = jax.jit(lambda k, s: env.step_batch(k, s, actions, params))
    looped = jax.jit(jax.vmap(lambda k, s: env.step(k, s, jnp.ones(env.max_agents, jnp.int32),
                                                    params)))
    one, two = states, states
    ended = np.zeros(count, bool)
    for t in range(80):
        keys = jax.random.split(jax.random.key(400 + t), count)
        out_one, out_two = batched(keys, one), looped(keys, two)
        for a, b in zip(jax.tree.leaves(out_one), jax.tree.leaves(out_two), strict=True):
            a, b = np.asarray(a), np.asarray(b)
            if EXACT or not np.issubdtype(a.dtype, np.floating):
                np.testing.assert_array_equal(a, b, err_msg=f"step {t}")
            else:  # the suite's fast-compile flags round the two programs apart (test_env.py)
                np.testing.assert_allclose(a, b, rtol=1e-5, atol=2e-5, err_msg=f"step {t}")
        one, two = out_one[1], out_two[1]
        ended |= np.asarray(out_one[5]["episode_done"])
        nodes = np.asarray(one.world.humans.node_valid)
        goals = np.asarray(one.humans.goal)
        active = np.asarray(one.humans.active)
        assert all(nodes[i][goals[i][active[i]]].all() for i in range(count))
        assert np.isfinite(np.asarray(one.humans.x)).all()
    assert ended.any()  # a new world, with its own slots, came in


@pytest.mark.parametrize("key", range(20))
def test_random_goals_are_valid_nodes_other_than_the_current_one(key):
    valid = jnp.asarray(np.random.default_rng(key).uniform(size=12) < 0.5).at[3].set(True)
    current = jnp.full(200, 3, jnp.int32)
    goal = np.asarray(_random_other_node(jax.random.key(key), current, 12, valid))
    allowed = set(np.flatnonzero(np.asarray(valid)).tolist()) - {3}
    if allowed:
        assert set(goal.tolist()) == allowed  # every valid other node, and only those
    else:
        assert (goal == 3).all()
