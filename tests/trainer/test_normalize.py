"""The running observation and return statistics (train/algorithm/normalize.py) against numpy."""

import jax
import numpy as np

from train.algorithm.normalize import RunningStats


def test_masked_running_statistics_equal_numpy_over_the_masked_rows():
    rng = np.random.default_rng(0)
    batches = [rng.normal(3.0, 2.0, (64, 5)).astype(np.float32) for _ in range(4)]
    masks = [rng.random(64) < share for share in (0.5, 0.0, 1.0, 0.2)]  # one batch all masked
    update = jax.jit(RunningStats.update)
    stats = RunningStats.start(5)
    for x, mask in zip(batches, masks, strict=True):
        before = stats
        stats = update(stats, x, mask)
        if not mask.any():  # no row counts: nothing changes
            for a, b in zip(jax.tree.leaves(before), jax.tree.leaves(stats), strict=True):
                np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    rows = np.concatenate([x[m] for x, m in zip(batches, masks, strict=True)]).astype(np.float64)
    # The start's prior (mean 0, variance 1, weight 1e-4) folded in as the update does.
    prior, n = 1e-4, len(rows)
    mean = rows.mean(0) * n / (n + prior)
    var = (prior * 1.0 + n * rows.var(0) + prior * n / (n + prior) * rows.mean(0) ** 2) / (
        n + prior)
    assert float(stats.count) == np.float32(prior + n)
    np.testing.assert_allclose(np.asarray(stats.mean), mean, rtol=1e-5)
    np.testing.assert_allclose(np.asarray(stats.var), var, rtol=1e-4)
    x = batches[0]
    np.testing.assert_allclose(np.asarray(stats.normalize(x)),
                               np.clip((x - mean) / np.sqrt(var + 1e-8), -10, 10), atol=1e-4)
