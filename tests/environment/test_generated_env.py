"""``sgjax.make("generated:<family>")``: every reset draws a world from its key into the
episode's state, the step and everything beside it (observations, metrics, policies) read the
episode's world, a batch of environments is a batch of worlds, and ``vmap(step)`` equals
``step_batch`` bitwise there too; bad ranges and pedestrians are refused by name."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.evaluation.evaluate import run_episodes


@pytest.fixture(scope="module")
def doorway():
    return sgjax.make("generated:doorway", num_agents=2, time_limit=4.0)


def test_resets_draw_a_world_per_key_and_the_same_key_the_same_world(doorway):
    env, params = doorway
    keys = jax.random.split(jax.random.key(0), 6)
    reset = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))
    _, states = reset(keys, params)
    _, again = reset(keys, params)
    widths = np.asarray(states.world.values["door_width"])
    assert len(set(np.round(widths, 5))) == 6 and np.all(np.asarray(states.world.valid))
    for a, b in zip(jax.tree.leaves(states), jax.tree.leaves(again), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    # the robots start in the episode's world: on its nodes
    for i in range(6):
        nodes = np.stack([states.world.map.node_x[i], states.world.map.node_y[i]], -1)
        starts = np.stack([states.robots.x[i], states.robots.y[i]], -1)[:2]
        assert np.min(np.abs(nodes[None] - starts[:, None]).sum(-1), axis=1).max() < 1e-5


@pytest.mark.slow
def test_the_step_reads_the_episodes_world_and_an_ended_episode_draws_a_new_one(doorway):
    env, params = doorway
    keys = jax.random.split(jax.random.key(1), 4)
    _, states = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    params_of = jax.vmap(env.params_in, in_axes=(0, None))(states, params)
    np.testing.assert_array_equal(params_of.map.zone_rect, states.world.map.zone_rect)
    obs = jax.vmap(env.observe)(states, params_of)
    np.testing.assert_array_equal(obs, jax.vmap(env.observe, in_axes=(0, None))(states, params))
    step = jax.jit(lambda k, s, a: env.step_batch(k, s, a, params))
    actions = jnp.zeros((4, env.max_agents), jnp.int32)  # GO: the planner drives
    before = np.asarray(states.world.values["door_width"])
    ended = np.zeros(4, bool)
    for t in range(45):  # past the 4 s time limit: every episode ends once
        states_next = step(jax.random.split(jax.random.key(100 + t), 4), states, actions)[1]
        done = np.asarray(step(jax.random.split(jax.random.key(100 + t), 4), states,
                               actions)[5]["episode_done"])
        widths = np.asarray(states_next.world.values["door_width"])
        assert np.array_equal(widths[~done], np.asarray(states.world.values["door_width"])[~done])
        ended |= done
        states = states_next
    assert ended.all()
    assert not np.array_equal(np.asarray(states.world.values["door_width"]), before)


@pytest.mark.slow
def test_vmap_of_step_equals_step_batch_on_generated_worlds(doorway):
    env, params = doorway
    keys = jax.random.split(jax.random.key(2), 3)
    _, states = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    actions = jnp.zeros((3, env.max_agents), jnp.int32)
    batched = jax.jit(lambda k, s: env.step_batch(k, s, actions, params))
    looped = jax.jit(jax.vmap(lambda k, s, a: env.step(k, s, a, params)))
    one, two = states, states
    for t in range(42):
        step_keys = jax.random.split(jax.random.key(200 + t), 3)
        out_one, out_two = batched(step_keys, one), looped(step_keys, two, actions)
        for a, b in zip(jax.tree.leaves(out_one), jax.tree.leaves(out_two), strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b), err_msg=f"step {t}")
        one, two = out_one[1], out_two[1]


def test_evaluation_plays_generated_worlds_and_reads_their_zones(doorway):
    env, params = doorway
    episodes = run_episodes(env, params, "only_local", jax.random.key(3), 4)
    assert episodes.values["team_success"].shape == (4,)
    assert np.all(np.isfinite(episodes.values["episode_length"]))


def test_bad_families_ranges_and_pedestrian_options_are_refused_by_name():
    with pytest.raises(ValueError, match="no world family 'dorway'.*doorway"):
        sgjax.make("generated:dorway")
    with pytest.raises(ValueError, match="no parameter 'door_widht'"):
        sgjax.make("generated:doorway", world_ranges={"door_widht": [1, 2]})
    with pytest.raises(ValueError, match="world_ranges: 'door_width': expected"):
        sgjax.make("generated:doorway", world_ranges={"door_width": [1, 2, 3]})
    # what the config fuzzer found: a row that is no sequence, a range that is None
    with pytest.raises(ValueError, match="world_ranges must be a mapping"):
        sgjax.make("generated:doorway", world_ranges=[{}])
    with pytest.raises(ValueError, match="world_ranges: '': expected"):
        sgjax.make("generated:doorway", world_ranges={"": None})
    with pytest.raises(ValueError, match="human_walls='points' needs a fixed map"):
        sgjax.make("generated:doorway", num_humans=2, human_walls="points")
    with pytest.raises(ValueError, match="human_goals='routes' needs a fixed map"):
        sgjax.make("generated:doorway", num_humans=2, human_goals="routes")
    env, _ = sgjax.make("generated:hallway", world_ranges={"corridor_width": 1.5})
    assert ("corridor_width", 1.5, 1.5) in env.config.world.ranges


def test_a_range_named_with_its_family_applies_to_that_family_alone():
    """``"<family>.<parameter>"`` sets one family's range in a batch of several (the others
    leave it out); an unknown family or parameter behind the prefix is refused by name."""
    ranges = {"doorway.ways": [1.0, 1.0], "hallway.ways": [1.0, 2.0]}
    doorway, _ = sgjax.make("generated:doorway", world_ranges=ranges)
    hallway, _ = sgjax.make("generated:hallway", world_ranges=ranges)
    crossing, _ = sgjax.make("generated:intersection", world_ranges=ranges)
    assert ("ways", 1.0, 1.0) in doorway.config.world.ranges
    assert ("ways", 1.0, 2.0) in hallway.config.world.ranges
    assert not [r for r in crossing.config.world.ranges if r[0] == "ways"]
    # a one-way doorway: every robot's route runs left to right
    keys = jax.random.split(jax.random.key(0), 16)
    one_way, params = sgjax.make("generated:doorway", world_ranges=ranges, num_agents=3)
    _, states = jax.vmap(one_way.reset, in_axes=(0, None))(keys, params)
    x = np.asarray(states.route.x)
    present = np.asarray(states.robots.present)
    assert np.all(np.where(present, x[..., -1] > x[..., 0], True))
    with pytest.raises(ValueError, match="no world family 'dorway'"):
        sgjax.make("generated:intersection", world_ranges={"dorway.ways": 1.0})
    with pytest.raises(ValueError, match="no parameter 'wayz'"):
        sgjax.make("generated:intersection", world_ranges={"doorway.wayz": 1.0})
