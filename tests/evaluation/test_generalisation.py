"""The generalisation report (``sgjax.evaluation.generalisation``): a world played by its seed is
the world ``reset`` draws, the worst alpha% ranks by one rollout and scores by the other, the
plays are deterministic, and ``sgjax generalise`` writes its result with provenance and the
table made from it."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.command import main
from sgjax.evaluation.generalisation import (
    RANKED,
    REPORTED,
    play_rollout,
    play_worlds,
    play_worst,
    rollout_keys,
    table_markdown,
    world_players,
    worst_fraction,
)


@pytest.fixture(scope="module")
def doorway():
    env, params = sgjax.make("generated:doorway", num_agents=3, max_agents=3)
    return env, params.replace(min_agents=jnp.asarray(0, jnp.int32))


def test_reset_in_the_world_a_key_draws_is_that_keys_reset(doorway):
    env, params = doorway
    key = jax.random.key(3)
    world = env.config.world.draw(jax.random.split(key)[1])
    obs, state = env.reset(key, params)
    obs2, state2 = env.reset_in_world(key, params, world)
    # the same up to float32 rounding (the world drawn apart from the compiled reset)
    np.testing.assert_allclose(np.asarray(obs), np.asarray(obs2), rtol=1e-5, atol=1e-5)
    for a, b in zip(jax.tree.leaves(state), jax.tree.leaves(state2), strict=True):
        if jnp.issubdtype(a.dtype, jnp.floating):
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-5, atol=1e-5)
        elif not jax.dtypes.issubdtype(a.dtype, jax.dtypes.prng_key):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_a_world_by_its_seed_is_the_world_a_split_plays(doorway):
    from sgjax.maps.generated.family import generate, range_arrays
    from sgjax.maps.generated.splits import world_key

    env, _ = doorway
    source = env.config.world
    draw = source.of_seed(17)
    ranges = range_arrays({n: (lo, hi) for n, lo, hi in source.ranges})
    _, values = generate(source.family, world_key(17), ranges)
    for name, value in values.items():
        assert float(draw.values[name]) == float(value)
    with pytest.raises(ValueError, match="fixed map"):
        fixed, fixed_params = sgjax.make("doorway", num_agents=3)
        fixed.reset_in_world(jax.random.key(0), fixed_params, draw)


def test_worst_fraction_ranks_by_the_first_rollout_and_scores_the_second():
    first = np.asarray([1.0, 0.0, 1.0, 0.0, np.nan])
    second = np.asarray([0.0, 1.0, 0.0, 0.5, 0.0])
    assert worst_fraction(first, second, 0.5) == (0.75, 2)  # worlds 1 and 3 ranked worst
    assert worst_fraction(first, second, 0.1) == (1.0, 1)
    assert worst_fraction(first, second, 1.0) == (0.375, 4)  # the NaN world left out
    with pytest.raises(ValueError, match="alpha"):
        worst_fraction(first, second, 0.0)


def test_plays_are_deterministic_and_the_two_rollouts_differ(doorway):
    env, params = doorway
    seeds = np.arange(12)
    one = play_worlds(env, params, "only_local", seeds, seed=5, chunk=8)
    two = play_worlds(env, params, "only_local", seeds, seed=5, chunk=8)
    assert one.valid.all() and one.a["team_success"].shape == (12,)
    for name in REPORTED:
        np.testing.assert_array_equal(one.a[name], two.a[name])
        np.testing.assert_array_equal(one.b[name], two.b[name])
    # other spawns and robot draws in rollout B: not the same episodes
    assert not np.array_equal(one.a["makespan"], one.b["makespan"], equal_nan=True)


def test_the_worst_case_replays_only_the_worlds_the_first_rollout_ranked_worst(doorway):
    """SFL's protocol: rollout A ranks every world as :func:`play_worlds` plays it, rollout B
    plays the worst max-alpha share alone, and each alpha scores B on its own share of it."""
    env, params = doorway
    seeds = np.arange(16)
    players = world_players(env, params, "only_local", 8)
    both = play_worlds(env, params, "only_local", seeds, seed=3, chunk=8, compiled=players)
    worst = play_worst(env, params, "only_local", seeds, [0.25, 0.5], seed=3, chunk=8,
                       compiled=players)
    np.testing.assert_array_equal(worst.ranked, both.a[RANKED])
    scored = np.flatnonzero(np.isfinite(both.a[RANKED]))
    assert worst.scored == len(scored) and len(worst.worst) == int(np.ceil(0.5 * len(scored)))
    ranks = both.a[RANKED][worst.worst]
    assert np.all(np.diff(ranks) >= 0)  # lowest first
    others = np.setdiff1d(scored, worst.worst)
    assert ranks.max() <= both.a[RANKED][others].min()  # nothing better kept, nothing worse left
    # rollout B: those worlds alone, keyed as play_worlds keys B
    _, replay = play_rollout(*players, params, seeds[worst.worst], rollout_keys(3)[1])
    np.testing.assert_array_equal(worst.second, replay[RANKED])
    count = int(np.ceil(0.25 * len(scored)))
    assert worst.fraction(0.25) == (float(np.mean(replay[RANKED][:count])), count)
    # the same worlds as worst_fraction over both rollouts would pick
    assert worst.fraction(0.5)[1] == worst_fraction(both.a[RANKED], both.b[RANKED], 0.5)[1]
    with pytest.raises(ValueError, match="played the worst"):
        worst.fraction(0.75)
    with pytest.raises(ValueError, match="alpha"):
        play_worst(env, params, "only_local", seeds, [0.0], compiled=players)


def test_sgjax_generalise_writes_the_result_and_its_table(tmp_path, capsys):
    main(["generalise", "--family", "doorway", "--worlds", "6", "--chunk", "6", "--alpha",
          "0.5", "--num-agents", "2", "--out", str(tmp_path)])
    result = json.loads((tmp_path / "generalisation.json").read_text())
    assert result["provenance"]["episodes_per_cell"] == 12
    (row,) = result["rows"]
    assert set(row["splits"]) == {"train", "test"} and set(row["gap"]) == set(REPORTED)
    assert (tmp_path / "generalisation.md").read_text() == table_markdown(result)
    assert "worst 50%" in capsys.readouterr().out
