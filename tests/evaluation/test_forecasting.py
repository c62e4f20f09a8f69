"""Forecast scores (``sgjax.evaluation.forecasting``): the constant-velocity forecast is exact
on straight walkers and off by the known amount on an accelerating one, predicted collisions
are found between rows too, ``jit`` equals eager; on the five ETH/UCY scenes (observe 8,
predict 12) its errors are those of people, not of a broken reader."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from shared_data import SHARED, require

from sgjax.evaluation.forecasting import (
    constant_velocity,
    forecast_windows,
    predicted_collisions,
    score_forecast,
    scored,
)
from sgjax.humans.tracks import read_tracks, write_rollout_tracks

SCENES = {"ETH": "biwi_eth.txt", "HOTEL": "biwi_hotel.txt", "UNIV": "students001.txt",
          "ZARA1": "crowds_zara01.txt", "ZARA2": "crowds_zara02.txt"}


def recording(tmp_path, x, y, active=None):
    active = np.ones(x.shape, bool) if active is None else active
    return read_tracks(write_rollout_tracks(tmp_path / "walk.txt", x, y, active))


def test_constant_velocity_is_exact_on_straight_walkers(tmp_path):
    t = np.arange(30, dtype=np.float32)[:, None]
    x = 0.5 * t * np.asarray([[1.0, -1.0, 0.3]]) + np.asarray([[0.0, 20.0, 5.0]])
    y = 0.5 * t * np.asarray([[0.2, 0.0, 1.0]]) + np.asarray([[0.0, 3.0, -4.0]])
    windows = forecast_windows(recording(tmp_path, x, y))
    assert windows.x.shape == (11, 20, 3)
    scores = score_forecast(*constant_velocity(windows), windows)
    assert float(scores.ade) < 1e-4 and float(scores.fde) < 1e-4
    assert float(scores.collisions) == 0.0 and int(scores.pedestrians) == 33


def test_an_accelerating_walker_is_missed_by_the_known_amount(tmp_path):
    """x = a t^2 / 2 (rows of 0.4 s, a in m/row^2): holding the last velocity misses by
    a (k^2 + k) / 2 after k rows (the velocity of the last observed step lags by half a
    row)."""
    a = 0.02
    t = np.arange(20, dtype=np.float32)[:, None]
    windows = forecast_windows(recording(tmp_path, 0.5 * a * t * t, np.zeros_like(t)))
    scores = score_forecast(*constant_velocity(windows), windows)
    k = np.arange(1, 13)
    expected = a * (k * k + k) / 2
    assert float(scores.fde) == pytest.approx(expected[-1], rel=1e-4)
    assert float(scores.ade) == pytest.approx(expected.mean(), rel=1e-4)


def test_collisions_are_found_at_rows_and_between_them(tmp_path):
    """Two walkers head-on along one line pass each other between two rows (never closer
    than 0.2 m at a row itself): a collision; the same walkers 1 m apart sideways: none."""
    t = np.arange(20, dtype=np.float32)
    x = np.stack([-6.2 + 0.5 * t, 6.2 - 0.5 * t], axis=1)
    for offset, hits in ((0.0, True), (1.0, False)):
        y = np.stack([np.zeros(20), np.full(20, offset)], axis=1).astype(np.float32)
        windows = forecast_windows(recording(tmp_path, x, y))
        px, py = constant_velocity(windows)
        rows = np.hypot(np.diff(np.asarray(px), axis=2), np.diff(np.asarray(py), axis=2))
        assert rows.min() >= 0.2 or not hits  # at the rows themselves they stay apart
        hit = predicted_collisions(px, py, scored(windows))
        assert bool(hit.all()) is hits


def test_scores_under_jit_equal_eager(tmp_path):
    rng = np.random.default_rng(0)
    x, y = (np.cumsum(rng.normal(0.4, 0.1, (40, 6)), axis=0).astype(np.float32)
            for _ in range(2))
    windows = forecast_windows(recording(tmp_path, x, y))
    eager = score_forecast(*constant_velocity(windows), windows)
    jitted = jax.jit(lambda w: score_forecast(*constant_velocity(w), w))(windows)
    for a, b in zip(jax.tree.leaves(eager), jax.tree.leaves(jitted), strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-6)


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_constant_velocity_on_the_eth_ucy_scenes(scene):
    """Observe 8, predict 12 over every fully observed pedestrian: errors of walking people
    (ADE 0.2-1.5 m, FDE above it), most forecasts without a collision."""
    path = require(SHARED / "pedestrians" / "eth_ucy" / SCENES[scene], "the ETH/UCY recordings")
    windows = forecast_windows(read_tracks(path))
    scores = jax.jit(lambda w: score_forecast(*constant_velocity(w), w))(windows)
    assert int(scores.pedestrians) > 300
    assert 0.2 < float(scores.ade) < 1.5 and float(scores.fde) > float(scores.ade)
    assert float(scores.collisions) < 0.5
