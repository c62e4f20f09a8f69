"""``sgjax crowd fit`` (``sgjax.evaluation.crowd_fit``): a fit on recordings the test writes
(crowds that sgjax's own forecast walked with known constants) writes a result file with its
provenance and a table, recovers a Helbing constant as the Moussaid test recovers tau, and
refuses a missing scene by name."""

from __future__ import annotations

import json

import jsonschema
import numpy as np
import pytest

from sgjax.command import main
from sgjax.evaluation.calibration import fit_social_force
from sgjax.evaluation.crowd_fit import table
from sgjax.evaluation.force_forecast import social_force_forecast
from sgjax.evaluation.forecasting import forecast_windows
from sgjax.evaluation.result_schema import schema_for
from sgjax.humans.forces import SocialForceParams
from sgjax.humans.tracks import read_tracks, write_rollout_tracks

DT = 0.4


def crowd(path, seed, rows=60, people=6):
    """People crossing a square, each on a straight line at 0.5-1.2 m/s, as a track file."""
    rng = np.random.default_rng(seed)
    t = np.arange(rows, dtype=np.float32)[:, None]
    heading = rng.uniform(0.0, 2 * np.pi, people)
    speed = rng.uniform(0.5, 1.2, people) * DT
    x = rng.uniform(-3, 3, (1, people)) + speed * t * np.cos(heading)
    y = rng.uniform(-3, 3, (1, people)) + speed * t * np.sin(heading)
    return write_rollout_tracks(path, x.astype(np.float32), y.astype(np.float32),
                                np.ones(x.shape, bool))


def test_crowd_fit_writes_a_result_with_provenance_and_a_table(tmp_path, capsys):
    data = tmp_path / "data"
    data.mkdir()
    for k, stem in enumerate(("walk_a", "walk_b", "walk_c")):
        crowd(data / f"{stem}.txt", k)
    main(["crowd", "fit", "--model", "moussaid", "--data", str(data), "--test", "walk_c",
          "--train", "walk_a", "walk_b", "--steps", "3", "--out", str(tmp_path / "out")])
    result = json.loads((tmp_path / "out" / "crowd_fit.json").read_text())
    assert result["schema_version"] == "sgjax.crowd_fit/1"
    jsonschema.validate(result, schema_for(result))
    assert {"git", "versions", "machine", "command"} <= set(result["provenance"])
    row = result["rows"][0]
    assert row["train"] == ["walk_a", "walk_b"] and row["test"] == "walk_c"
    assert row["steps"] == 3 and set(row["constants"]) == {
        "tau", "social_strength", "lambda_importance", "gamma", "n", "n_prime"}
    for name in ("constant_velocity", "published", "fitted"):
        assert row["scores"][name]["ade"] >= 0.0 and row["scores"][name]["pedestrians"] > 0
    for diff in row["fitted_minus"].values():
        assert diff["ci_low"] <= diff["mean"] <= diff["ci_high"] and diff["windows"] >= 2
    markdown = (tmp_path / "out" / "crowd_fit.md").read_text()
    assert markdown.strip() == table(result) and "| moussaid | walk_c |" in markdown
    assert "walk_c" in capsys.readouterr().out


def test_crowd_fit_refuses_a_missing_scene_by_name(tmp_path):
    with pytest.raises(SystemExit, match="no track file nowhere.txt for scene 'nowhere'"):
        main(["crowd", "fit", "--data", str(tmp_path), "--test", "nowhere", "--train", "x",
              "--out", str(tmp_path / "out")])
    with pytest.raises(ValueError, match="model must be one of"):
        fit_social_force([], DT, model="orca")


def test_a_fit_recovers_the_helbing_range_of_a_simulated_crowd(tmp_path):
    """Tracks walked by the Helbing forecast with sigma = 0.6 m: a fit of sigma alone from
    the published 0.3 m lowers the one-row loss and moves sigma halfway towards 0.6 at
    least (a broken gradient leaves it where it started)."""
    windows = forecast_windows(read_tracks(crowd(tmp_path / "c.txt", 5, rows=30, people=8)),
                               stride=2)
    truth = SocialForceParams(sigma=0.6, v0=4.0)
    px, py = social_force_forecast(truth, windows, DT, model="helbing")
    windows = windows.replace(x=windows.x.at[:, 8:].set(px), y=windows.y.at[:, 8:].set(py))
    start = SocialForceParams(v0=4.0)
    fitted, history = fit_social_force([windows], DT, steps=60, names=("sigma",),
                                       model="helbing", start=start)
    assert history[-1] < 0.5 * history[0]
    assert abs(float(fitted.sigma) - 0.6) < abs(0.3 - 0.6) / 2
