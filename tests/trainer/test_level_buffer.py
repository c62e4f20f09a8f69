"""The level buffer of the curricula over generated worlds (PLR, ACCEL, learnability), against
plain-Python references over many random keys: replay weights, edits within ranges, episode
scores across rollouts, and what a rollout's ended episodes do to the buffer."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from train.algorithm.level_buffer import (
    Crowd,
    LevelBuffer,
    edit,
    episode_scores,
    next_levels,
    record,
    replay_weights,
    step_scores,
)

RANGES = {"a": (0.0, 1.0), "b": (2.0, 4.0), "fixed": (3.0, 3.0)}


def _buffer(size=6, envs=3, filled=4, seed=0):
    rng = np.random.default_rng(seed)
    buffer = LevelBuffer.empty(tuple(RANGES), size, envs)
    live = np.arange(size) < filled
    return buffer.replace(
        seed=jnp.asarray(np.arange(size) + 100, jnp.uint32),
        values={"a": jnp.asarray(rng.uniform(0, 1, size), jnp.float32),
                "b": jnp.asarray(rng.uniform(2, 4, size), jnp.float32),
                "fixed": jnp.full(size, 3.0, jnp.float32)},
        score=jnp.asarray(np.where(live, rng.uniform(0, 1, size), -np.inf), jnp.float32),
        plays=jnp.asarray(live, jnp.float32), success=jnp.asarray(live * 0.5, jnp.float32),
        last_played=jnp.asarray(rng.integers(0, 50, size), jnp.int32),
        filled=jnp.asarray(live))


@pytest.mark.parametrize("key", range(20))
def test_replay_weights_are_plrs_rank_and_staleness_mixture(key):
    buffer = _buffer(size=8, filled=1 + key % 8, seed=key)
    now, temperature, staleness = 60, 0.3, 0.3
    w = np.asarray(replay_weights(buffer, jnp.int32(now), temperature, staleness))
    filled = np.asarray(buffer.filled)
    score = np.asarray(buffer.score)
    order = sorted(np.flatnonzero(filled), key=lambda i: -score[i])
    rank = {i: r + 1 for r, i in enumerate(order)}
    h = np.array([(1 / rank[i]) ** (1 / temperature) if filled[i] else 0 for i in range(8)])
    age = np.where(filled, now - np.asarray(buffer.last_played), 0).astype(float)
    expect = 0.7 * h / h.sum() + 0.3 * age / age.sum()
    np.testing.assert_allclose(w, expect, rtol=1e-5, atol=1e-7)
    assert w[~filled].sum() == 0 and w.sum() == pytest.approx(1.0, abs=1e-5)


@pytest.mark.parametrize("key", range(30))
def test_an_edit_moves_at_most_edits_parameters_within_their_ranges(key):
    values = {"a": jnp.float32(0.5), "b": jnp.float32(3.0), "fixed": jnp.float32(3.0)}
    edits = 1 + key % 2
    out, pedestrians = edit(jax.random.key(key), values, jnp.int32(-1), RANGES, edits, 0.5)
    out = {k: float(v) for k, v in out.items()}
    assert int(pedestrians) == -1  # no crowd: never a group
    moved = [k for k in values if out[k] != float(values[k])]
    assert len(moved) <= edits and "fixed" not in moved
    assert all(RANGES[k][0] <= out[k] <= RANGES[k][1] for k in out)
    assert all(abs(out[k] - float(values[k])) <= 0.5 * (RANGES[k][1] - RANGES[k][0]) + 1e-6
               for k in out)


def test_edits_reach_every_movable_parameter_and_both_directions():
    values = {"a": jnp.float32(0.5), "b": jnp.float32(3.0), "fixed": jnp.float32(3.0)}
    outs, _ = jax.vmap(lambda k: edit(k, values, jnp.int32(-1), RANGES, 1, 0.2))(
        jax.random.split(jax.random.key(0), 200))
    for name in ("a", "b"):
        d = np.asarray(outs[name]) - float(values[name])
        assert (d > 0).any() and (d < 0).any()


@pytest.mark.parametrize("key", range(10))
def test_episode_scores_are_means_over_whole_episodes_across_rollouts(key):
    rng = np.random.default_rng(key)
    envs, steps, rollouts = 3, 7, 4
    buffer = LevelBuffer.empty(tuple(RANGES), 4, envs)
    total, count = np.zeros(envs), np.zeros(envs)
    for _ in range(rollouts):
        scores = rng.uniform(0, 2, (steps, envs)).astype(np.float32)
        acted = rng.uniform(size=(steps, envs)) < 0.8
        done = rng.uniform(size=(steps, envs)) < 0.2
        out, buffer = episode_scores(buffer, jnp.asarray(scores), jnp.asarray(acted),
                                     jnp.asarray(done))
        for t in range(steps):
            total += np.where(acted[t], scores[t], 0)
            count += acted[t]
            for e in np.flatnonzero(done[t]):
                assert float(out[t, e]) == pytest.approx(total[e] / max(count[e], 1), rel=1e-5)
                total[e], count[e] = 0, 0
            assert np.all(np.asarray(out[t])[~done[t]] == 0)
    np.testing.assert_allclose(np.asarray(buffer.episode_score), total, rtol=1e-5)
    np.testing.assert_allclose(np.asarray(buffer.episode_steps), count)


def test_step_scores_are_the_acting_robots_mean_positive_advantage():
    adv = jnp.asarray([[1.0, -2.0, 3.0, 0.5], [-1.0, -1.0, 2.0, 2.0]])  # [T=2, E=2 x R=2]
    active = jnp.asarray([[True, True, False, True], [False, False, True, True]])
    scores, stepped = step_scores(adv, active, 2)
    np.testing.assert_allclose(np.asarray(scores), [[0.5, 0.5], [0.0, 2.0]])
    np.testing.assert_array_equal(np.asarray(stepped), [[True, True], [False, True]])


def _events(seeds, a, b, done, score, success, valid=None, pedestrians=None):
    shape = (1, len(seeds))
    arr = lambda x, t: jnp.asarray(np.asarray(x).reshape(shape), t)  # noqa: E731
    return dict(seed=arr(seeds, jnp.uint32),
                pedestrians=arr(np.full(len(seeds), -1) if pedestrians is None
                                else pedestrians, jnp.int32),
                values={"a": arr(a, jnp.float32), "b": arr(b, jnp.float32),
                        "fixed": arr(np.full(len(seeds), 3.0), jnp.float32)},
                valid=arr(np.ones(len(seeds), bool) if valid is None else valid, bool),
                done=arr(done, bool), score=arr(score, jnp.float32),
                success=arr(success, jnp.float32))


def test_record_updates_held_levels_and_keeps_the_best_new_ones():
    buffer = _buffer(size=4, envs=5, filled=3, seed=1)
    held_seed, held_a, held_b = 101, float(buffer.values["a"][1]), float(buffer.values["b"][1])
    low = int(np.argmin(np.where(buffer.filled, buffer.score, np.inf)))
    events = _events(
        seeds=[held_seed, 7, 7, 8, 9],
        a=[held_a, 0.1, 0.1, 0.2, 0.3], b=[held_b, 2.5, 2.5, 2.6, 2.7],
        done=[True, True, True, True, False], score=[5.0, 9.0, 9.0, -1.0, 50.0],
        success=[1.0, 0.5, 0.5, 0.5, 0.5], valid=[True, True, True, True, True])
    out, episodes, replays = record(buffer, jnp.int32(77), learnability=False, candidates=5,
                                    **events)
    assert float(episodes) == 4 and float(replays) == 1  # 101 was held
    seeds = np.asarray(out.seed)[np.asarray(out.filled)].tolist()
    assert seeds.count(7) == 1  # a level played twice in a rollout is kept once...
    assert float(np.asarray(out.plays)[np.asarray(out.filled)][seeds.index(7)]) == 2  # twice
    assert 9 not in seeds  # an episode still going is not recorded
    assert held_seed in seeds and 8 not in seeds  # 8 scores below the others: no slot
    i = seeds.index(held_seed)
    assert float(np.asarray(out.score)[np.asarray(out.filled)][i]) == 5.0
    assert int(np.asarray(out.last_played)[np.asarray(out.filled)][i]) == 77
    assert np.asarray(out.filled).all()
    assert int(buffer.seed[low]) in seeds  # every old level outscores 8's -1


def test_record_refuses_invalid_worlds_and_learnability_scores_success():
    buffer = LevelBuffer.empty(tuple(RANGES), 4, 3)
    events = _events(seeds=[1, 2, 3], a=[0.1, 0.2, 0.3], b=[2, 3, 4], done=[True] * 3,
                     score=[1.0, 1.0, 1.0], success=[0.5, 1.0, 0.25], valid=[True, True, False])
    out, _, _ = record(buffer, jnp.int32(5), learnability=True, candidates=3, **events)
    filled = np.asarray(out.filled)
    assert sorted(np.asarray(out.seed)[filled].tolist()) == [1, 2]
    by_seed = dict(zip(np.asarray(out.seed)[filled].tolist(),
                       np.asarray(out.score)[filled].tolist(), strict=True))
    assert by_seed == {1: 0.25, 2: 0.0}
    # played again and failed: p = (0.5 + 0) / 2, learnability 0.25 x 0.75
    again = _events(seeds=[1, 1, 5], a=[0.1, 0.1, 0.9], b=[2, 2, 2], done=[True, False, False],
                    score=[0, 0, 0], success=[0.0, 0.0, 0.0])
    out, _, replays = record(out, jnp.int32(9), learnability=True, candidates=3, **again)
    assert float(replays) == 1
    i = int(np.flatnonzero(np.asarray(out.filled) & (np.asarray(out.seed) == 1))[0])
    assert float(out.plays[i]) == 2 and float(out.score[i]) == pytest.approx(0.1875)


@pytest.mark.parametrize("key", range(8))
def test_next_levels_replay_only_from_a_filled_enough_buffer(key):
    kwargs = dict(min_fill=0.5, temperature=0.3, staleness=0.3, edits=1, edit_scale=0.2)
    k = jax.random.key(key)
    thin = _buffer(size=8, envs=16, filled=3, seed=key)
    level = next_levels(k, thin, jnp.int32(60), RANGES, replay_prob=1.0, mutate_prob=0.0,
                        **kwargs)
    assert not np.asarray(level.chosen).any()
    empty = LevelBuffer.empty(tuple(RANGES), 8, 16)  # min_fill 0 never replays nothing
    level = next_levels(k, empty, jnp.int32(60), RANGES, replay_prob=1.0, mutate_prob=0.0,
                        **{**kwargs, "min_fill": 0.0})
    assert not np.asarray(level.chosen).any()
    full = _buffer(size=8, envs=16, filled=6, seed=key)
    level = next_levels(k, full, jnp.int32(60), RANGES, replay_prob=1.0, mutate_prob=0.0,
                        **kwargs)
    assert np.asarray(level.chosen).all()
    slots = [int(np.flatnonzero(np.asarray(full.seed) == s)[0]) for s in np.asarray(level.seed)]
    assert all(bool(full.filled[s]) for s in slots)
    for name in RANGES:  # PLR replays the level as it is
        np.testing.assert_array_equal(np.asarray(level.values[name]),
                                      np.asarray(full.values[name])[slots])
    edited = next_levels(k, full, jnp.int32(60), RANGES, replay_prob=1.0, mutate_prob=1.0,
                         **kwargs)
    changed = sum(not np.array_equal(np.asarray(edited.values[n]), np.asarray(level.values[n]))
                  for n in RANGES)
    assert changed >= 1 and np.array_equal(np.asarray(edited.seed), np.asarray(level.seed))


CROWD = Crowd(group=3, base=2, capacity=8)


@pytest.mark.parametrize("key", range(30))
def test_an_edit_may_add_a_pedestrian_group_up_to_the_capacity(key):
    values = {"a": jnp.float32(0.5), "b": jnp.float32(3.0), "fixed": jnp.float32(3.0)}
    start = [-1, 2, 5, 7, 8][key % 5]
    edits = 1 + key % 3
    out, pedestrians = edit(jax.random.key(key), values, jnp.int32(start), RANGES, edits, 0.2,
                            CROWD)
    moved = sum(float(out[k]) != float(values[k]) for k in values)
    count = CROWD.base if start < 0 else start  # -1: the environment's own
    grown = {min(count + g * CROWD.group, CROWD.capacity) for g in range(1, edits + 1)
             if count < CROWD.capacity}  # whole groups, capped; none once full
    assert int(pedestrians) in {start} | grown
    assert moved + (int(pedestrians) != start) <= edits


def test_groups_are_added_as_often_as_a_parameter_is_moved():
    values = {"a": jnp.float32(0.5), "b": jnp.float32(3.0), "fixed": jnp.float32(3.0)}
    outs, pedestrians = jax.vmap(lambda k: edit(k, values, jnp.int32(-1), RANGES, 1, 0.2,
                                                CROWD))(jax.random.split(jax.random.key(1), 600))
    grown = np.asarray(pedestrians) == CROWD.base + CROWD.group
    assert set(np.unique(np.asarray(pedestrians)).tolist()) == {-1, CROWD.base + CROWD.group}
    assert 0.25 < grown.mean() < 0.42  # one choice of three (a, b, a group)
    assert np.all(np.asarray(outs["a"])[grown] == 0.5)  # the group was the edit
    _, never = jax.vmap(lambda k: edit(k, values, jnp.int32(-1), RANGES, 1, 0.2,
                                       Crowd(group=3, base=8, capacity=8)))(
        jax.random.split(jax.random.key(1), 100))
    assert np.all(np.asarray(never) == -1)  # full: no group


def test_a_replayed_level_keeps_its_pedestrians_and_a_fresh_one_has_the_environments():
    kwargs = dict(min_fill=0.5, temperature=0.3, staleness=0.3, edits=1, edit_scale=0.2)
    full = _buffer(size=8, envs=64, filled=8).replace(
        pedestrians=jnp.arange(8, dtype=jnp.int32) % 3)
    k = jax.random.key(0)
    level = next_levels(k, full, jnp.int32(60), RANGES, replay_prob=0.5, mutate_prob=0.0,
                        crowd=CROWD, **kwargs)
    chosen = np.asarray(level.chosen)
    slots = [int(np.flatnonzero(np.asarray(full.seed) == s)[0]) for s in np.asarray(level.seed)]
    expect = np.where(chosen, np.asarray(full.pedestrians)[slots], -1)
    np.testing.assert_array_equal(np.asarray(level.pedestrians), expect)
    assert chosen.any() and (~chosen).any()
    edited = next_levels(k, full, jnp.int32(60), RANGES, replay_prob=1.0, mutate_prob=1.0,
                         crowd=CROWD, **kwargs)
    assert (np.asarray(edited.pedestrians) > np.asarray(full.pedestrians)[
        [int(np.flatnonzero(np.asarray(full.seed) == s)[0]) for s in
         np.asarray(edited.seed)]]).any()


def test_levels_that_differ_in_pedestrians_alone_are_two_levels():
    buffer = LevelBuffer.empty(tuple(RANGES), 4, 3)
    events = _events(seeds=[1, 1, 1], a=[0.1] * 3, b=[2.0] * 3, done=[True] * 3,
                     score=[1.0, 2.0, 3.0], success=[0.5] * 3, pedestrians=[-1, 4, 4])
    out, _, _ = record(buffer, jnp.int32(5), learnability=False, candidates=3, **events)
    filled = np.asarray(out.filled)
    assert sorted(np.asarray(out.pedestrians)[filled].tolist()) == [-1, 4]
    four = int(np.flatnonzero(filled & (np.asarray(out.pedestrians) == 4))[0])
    assert float(out.plays[four]) == 2 and float(out.score[four]) == pytest.approx(2.5)
