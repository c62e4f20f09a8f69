"""Intervals a reviewer accepts (``sgjax.evaluation.statistics``): over training seeds and
episodes together, never the range of a few seeds, and the across-cell aggregates (IQM,
probability of improvement, performance profile) with stratified bootstrap intervals."""

from __future__ import annotations

import numpy as np
import pytest


def test_the_two_level_bootstrap_covers_the_truth_where_episodes_alone_do_not():
    """Synthetic trained policies whose seeds differ (seed effects of sd 0.15 around +0.2) on
    100 shared yes/no episodes: the two-level interval covers the true difference close to 95%
    of the time (a percentile bootstrap over 5 seeds runs a little narrow); the t interval over
    episodes of the seed-averaged difference (seeds left out) covers it far less often."""
    from sgjax.evaluation.statistics import paired_difference, paired_over_seeds_and_episodes

    rng = np.random.default_rng(0)
    truth, covered, naive = 0.2, 0, 0
    trials = 120
    for _ in range(trials):
        p = np.clip(0.5 + truth + rng.normal(0, 0.15, 5), 0, 1)  # 5 seeds
        a = (rng.random((5, 100)) < p[:, None]).astype(float)
        b = (rng.random(100) < 0.5).astype(float)
        # the true difference: the mean over the seed distribution
        two = paired_over_seeds_and_episodes(a, b, resamples=400, seed=1)
        covered += two.ci_low <= truth <= two.ci_high
        one = paired_difference(a.mean(axis=0), b)
        naive += one.ci_low <= truth <= one.ci_high
    assert covered / trials > 0.85
    assert naive / trials < covered / trials - 0.07


@pytest.mark.parametrize("trial", range(6))
def test_the_two_level_bootstrap_is_a_loop_of_seed_then_episode_draws(trial):
    """Its resamples, drawn and averaged in one pass, are the loop that defines them: per
    resample ``S`` seeds then ``E`` episodes drawn with replacement from one generator, the
    NaN-aware mean of the picked block; the interval's ends agree to rounding (NaN cells,
    one seed, one episode, continuous values included)."""
    from sgjax.evaluation.statistics import paired_over_seeds_and_episodes

    rng = np.random.default_rng(trial)
    seeds, episodes = [(5, 100), (1, 40), (3, 1), (7, 13), (2, 250), (4, 60)][trial]
    a = (rng.random((seeds, episodes)) < 0.7).astype(float)
    if trial % 2:
        a = rng.normal(size=(seeds, episodes))
    a[rng.random(a.shape) < 0.15] = np.nan
    b = (rng.random(episodes) < 0.5).astype(float)
    diff, draws = a - b, np.random.default_rng(trial + 10)
    means = []
    for _ in range(300):
        rows = draws.integers(0, seeds, seeds)
        cols = draws.integers(0, episodes, episodes)
        block = diff[np.ix_(rows, cols)]
        means.append(np.nanmean(block) if np.isfinite(block).any() else np.nan)
    low, high = np.nanquantile(means, [0.025, 0.975])
    got = paired_over_seeds_and_episodes(a, b, resamples=300, seed=trial + 10)
    assert got.ci_low == pytest.approx(low, abs=1e-12)
    assert got.ci_high == pytest.approx(high, abs=1e-12)
    assert got.mean == pytest.approx(np.nanmean(diff))


def test_per_seed_t_intervals_are_never_the_range_of_the_seeds():
    from sgjax.evaluation.statistics import per_seed_paired_t, seed_aggregate

    a = np.asarray([[1.0] * 10, [0.8] * 10, [0.9] * 10])
    t = per_seed_paired_t(a, np.zeros(10))
    assert t.n == 3 and t.mean == pytest.approx(0.9)
    assert t.ci_low < 0.8 and t.ci_high > 1.0  # wider than the seeds' range [0.8, 1.0]
    boot = seed_aggregate(a.mean(axis=1))
    assert boot["mean_low"] >= 0.8 - 1e-9 and boot["mean_high"] <= 1.0 + 1e-9  # the range


def test_aggregates_over_cells_with_stratified_bootstrap():
    from sgjax.evaluation.statistics import (
        aggregate_over_cells,
        improvement_over_cells,
        performance_profile,
    )

    cells = {"doorway/3": np.asarray([0.9, 0.8, 0.85]), "hallway/3": np.asarray([0.5, 0.6]),
             "open/3": np.asarray([0.1, 0.2, 0.15, 0.3])}
    agg = aggregate_over_cells(cells, resamples=500)
    assert agg["runs"] == 9 and agg["cells"] == 3
    assert agg["iqm_low"] <= agg["iqm"] <= agg["iqm_high"]
    assert agg["mean_low"] <= agg["mean"] <= agg["mean_high"]
    same = {c: np.full(4, 0.7) for c in cells}
    flat = aggregate_over_cells(same, resamples=100)
    assert flat["iqm"] == flat["iqm_low"] == flat["iqm_high"] == pytest.approx(0.7)
    better = {c: v + 1.0 for c, v in cells.items()}
    up = improvement_over_cells(better, cells, resamples=200)
    assert up["probability"] == up["low"] == up["high"] == 1.0 and up["cells"] == 3
    even = improvement_over_cells(cells, cells, resamples=200)
    assert even["probability"] == pytest.approx(0.5) and even["low"] <= 0.5 <= even["high"]
    with pytest.raises(ValueError, match="no cell in common"):
        improvement_over_cells({"a": np.ones(2)}, {"b": np.ones(2)})
    profile = performance_profile(cells, np.linspace(0, 1, 11), resamples=300)
    assert np.all(np.diff(profile["fraction"]) <= 0)
    assert np.all(profile["low"] <= profile["fraction"] + 1e-12)
    assert np.all(profile["fraction"] <= profile["high"] + 1e-12)
    assert profile["fraction"][0] == 1.0 and profile["fraction"][-1] == 0.0


def test_aggregates_over_cells_without_a_finite_score_are_refused_by_name():
    from sgjax.evaluation.statistics import aggregate_over_cells, performance_profile

    empty = {"doorway/3": np.asarray([np.nan, np.nan]), "open/3": np.asarray([])}
    with pytest.raises(ValueError, match="no finite score in any of the 2 cells"):
        aggregate_over_cells(empty, resamples=10)
    with pytest.raises(ValueError, match="no finite score"):
        performance_profile(empty, np.asarray([0.5]), resamples=10)


def test_the_batched_bootstrap_draws_what_a_loop_of_single_draws_draws():
    """The stratified resamples, the aggregates and P(improvement) over cells draw all their
    resamples in one generator call: the same numbers, and the same intervals, as one draw per
    resample per side (the loop the statistics describe), empty and NaN cells included."""
    import math

    from sgjax.evaluation.statistics import (
        aggregate_over_cells,
        improvement_over_cells,
        interquartile_mean,
        probability_of_improvement,
        resample_cells,
        stratified_resamples,
    )

    rng = np.random.default_rng(7)
    for trial in range(20):
        cells = {f"c{i}": rng.integers(0, 5, rng.integers(1, 7)) / 4.0 for i in range(6)}
        other = {f"c{i}": rng.integers(0, 5, rng.integers(1, 7)) / 4.0 for i in range(1, 7)}
        cells["c2"] = np.asarray([math.nan, *cells["c2"]])
        if trial % 4 == 0:
            other["c3"] = np.asarray([math.nan])  # a cell with nothing to draw on one side
        loop = np.random.default_rng(trial)
        rows = [np.concatenate(list(resample_cells(cells, loop).values())) for _ in range(50)]
        assert np.array_equal(stratified_resamples(cells, 50, trial), np.asarray(rows))
        iqm = np.quantile([interquartile_mean(r) for r in rows], [0.025, 0.975])
        agg = aggregate_over_cells(cells, resamples=50, seed=trial)
        assert [agg["iqm_low"], agg["iqm_high"]] == pytest.approx(iqm, abs=1e-12)
        shared = [c for c in cells if c in other]
        loop = np.random.default_rng(trial)
        values = []
        for _ in range(60):
            a = resample_cells({c: cells[c] for c in shared}, loop)
            b = resample_cells({c: other[c] for c in shared}, loop)
            values.append(np.nanmean([probability_of_improvement(a[c], b[c])
                                      if a[c].size and b[c].size else math.nan
                                      for c in shared]))
        p = improvement_over_cells(cells, other, resamples=60, seed=trial)
        assert [p["low"], p["high"]] == pytest.approx(np.nanquantile(values, [0.025, 0.975]),
                                                      abs=1e-12)
