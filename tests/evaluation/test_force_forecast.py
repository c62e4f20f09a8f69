"""Recorded pedestrians forecast by the Moussaid social force
(``sgjax.evaluation.force_forecast``): a lone walker goes on straight, two walkers head-on
step aside where the constant-velocity forecast runs them into each other, the one-row loss's
gradient matches finite differences, ``jit`` equals eager; on two ETH/UCY scenes it runs with
finite scores."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from shared_data import SHARED, require

from sgjax.evaluation.force_forecast import one_row_loss, social_force_forecast
from sgjax.evaluation.forecasting import constant_velocity, forecast_windows, score_forecast
from sgjax.humans.forces import SocialForceParams
from sgjax.humans.tracks import read_tracks, write_rollout_tracks

DT = 0.4


def windows_of(tmp_path, x, y):
    path = write_rollout_tracks(tmp_path / "walk.txt", x, y, np.ones(x.shape, bool))
    return forecast_windows(read_tracks(path, step_seconds=DT))


def test_a_lone_walker_goes_on_straight(tmp_path):
    t = np.arange(20, dtype=np.float32)[:, None]
    windows = windows_of(tmp_path, 0.5 * t, 0.2 * t)  # 1.35 m/s along a line
    scores = score_forecast(*social_force_forecast(SocialForceParams(), windows, DT), windows)
    assert float(scores.fde) < 1e-3


def test_walkers_head_on_step_aside_where_constant_velocity_collides(tmp_path):
    """Two people walking at each other along one line, 1.2 m/s each, 8 m apart at the end
    of the observation: held velocities meet; the social force turns them apart."""
    t = np.arange(20, dtype=np.float32)
    x = np.stack([-7.36 + 0.48 * t, 7.36 - 0.48 * t], axis=1)
    y = np.stack([np.full(20, 0.0), np.full(20, 0.05)], axis=1).astype(np.float32)
    windows = windows_of(tmp_path, x, y)
    cv = score_forecast(*constant_velocity(windows), windows)
    sf_x, sf_y = social_force_forecast(SocialForceParams(), windows, DT)
    sf = score_forecast(sf_x, sf_y, windows)
    assert float(cv.collisions) == 1.0 and float(sf.collisions) == 0.0
    gap = np.hypot(np.diff(np.asarray(sf_x), axis=2), np.diff(np.asarray(sf_y), axis=2))
    assert gap.min() > 0.3  # m between the two at every forecast row


def test_the_one_row_loss_gradient_matches_finite_differences(tmp_path):
    rng = np.random.default_rng(0)
    start = rng.uniform(-3.0, 3.0, (1, 5)).astype(np.float32)
    heading = rng.uniform(0.0, 2 * np.pi, 5)
    t = np.arange(22, dtype=np.float32)[:, None]
    x = start + 0.5 * t * np.cos(heading) + rng.normal(0, 0.02, (22, 5)).astype(np.float32)
    y = start[:, ::-1] + 0.5 * t * np.sin(heading) + rng.normal(0, 0.02, (22, 5))
    windows = windows_of(tmp_path, x.astype(np.float32), y.astype(np.float32))
    base = SocialForceParams()

    def loss(tau, strength, gamma):
        return one_row_loss(base.replace(tau=tau, social_strength=strength, gamma=gamma),
                            windows, DT)

    point = (jnp.float32(0.5), jnp.float32(5.1), jnp.float32(0.35))
    grads = jax.jit(jax.grad(loss, argnums=(0, 1, 2)))(*point)
    eager = jax.grad(loss, argnums=(0, 1, 2))(*point)
    for i, step in enumerate((1e-2, 1e-1, 1e-2)):
        up = list(point)
        down = list(point)
        up[i], down[i] = point[i] + step, point[i] - step
        numeric = (float(loss(*up)) - float(loss(*down))) / (2 * step)
        assert float(grads[i]) == pytest.approx(numeric, rel=0.05, abs=1e-6)
        assert float(eager[i]) == pytest.approx(float(grads[i]), rel=1e-4, abs=1e-8)
    assert any(abs(float(g)) > 1e-5 for g in grads)  # the loss depends on the constants


@pytest.mark.parametrize("name", ["biwi_hotel.txt", "crowds_zara01.txt"])
def test_the_social_force_forecasts_recorded_scenes(name):
    path = require(SHARED / "pedestrians" / "eth_ucy" / name, "the ETH/UCY recordings")
    tracks = read_tracks(path)
    windows = forecast_windows(tracks, stride=4)
    scores = jax.jit(lambda w: score_forecast(*social_force_forecast(
        SocialForceParams(), w, tracks.dt), w))(windows)
    assert np.isfinite(float(scores.ade)) and 0.1 < float(scores.ade) < 1.5
    assert float(scores.fde) > float(scores.ade)


@pytest.mark.slow
def test_a_fit_recovers_the_relaxation_time_of_a_simulated_crowd(tmp_path):
    """Tracks walked by the forecast's own model with tau = 1.2 s (five people crossing): a
    fit from the published 0.5 s lowers the one-row loss and moves tau towards 1.2."""
    from sgjax.evaluation.calibration import fit_social_force

    rng = np.random.default_rng(3)
    t = np.arange(24, dtype=np.float32)[:, None]
    heading = rng.uniform(0.0, 2 * np.pi, 5)
    x = rng.uniform(-2, 2, (1, 5)) + 0.45 * t * np.cos(heading)
    y = rng.uniform(-2, 2, (1, 5)) + 0.45 * t * np.sin(heading)
    windows = windows_of(tmp_path, x.astype(np.float32), y.astype(np.float32))
    truth = SocialForceParams(tau=1.2)
    px, py = social_force_forecast(truth, windows, DT)  # replace the forecast rows
    windows = windows.replace(x=windows.x.at[:, 8:].set(px), y=windows.y.at[:, 8:].set(py))
    fitted, history = fit_social_force([windows], DT, steps=60, names=("tau",))
    assert history[-1] < 0.5 * history[0]
    assert abs(float(fitted.tau) - 1.2) < abs(0.5 - 1.2) / 2
    with pytest.raises(ValueError, match="no SocialForceParams constant 'tua'"):
        fit_social_force([windows], DT, names=("tua",))
