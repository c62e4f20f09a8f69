"""``sgjax crowd fit`` (``sgjax.evaluation.crowd_fit``): a fit on recordings the test writes
(crowds that sgjax's own forecast walked with known constants) writes a result file with its
provenance and a table, recovers a Helbing constant as the Moussaid test recovers tau, and
refuses a missing scene by name; the headed model and ORCA recover theirs too, a fit goes on to
short rollouts, and Helbing's row carries TrajNet++'s constants."""

from __future__ import annotations

import json

import jsonschema
import numpy as np
import pytest

from sgjax.command import main
from sgjax.evaluation.calibration import fit_social_force
from sgjax.evaluation.crowd_fit import table
from sgjax.evaluation.force_forecast import one_row_loss, rollout_loss, social_force_forecast
from sgjax.evaluation.forecasting import forecast_windows
from sgjax.evaluation.result_schema import schema_for
from sgjax.humans.forces import SocialForceParams
from sgjax.humans.hsfm import HsfmParams
from sgjax.humans.orca_model import OrcaParams
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


@pytest.mark.slow
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
        fit_social_force([], DT, model="socialgym")


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


def _walked_by(truth, model, tmp_path, seed=5, people=8):
    """Windows of a crossing crowd whose forecast rows ``model`` walked with ``truth``."""
    windows = forecast_windows(read_tracks(crowd(tmp_path / "c.txt", seed, rows=30,
                                                 people=people)), stride=2)
    px, py = social_force_forecast(truth, windows, DT, model=model)
    return windows.replace(x=windows.x.at[:, 8:].set(px), y=windows.y.at[:, 8:].set(py))


@pytest.mark.parametrize("model, truth, name, start, goal, rows", [
    ("hsfm", HsfmParams(tau=1.0), "tau", 0.5, 1.0, 12),
    # ORCA's programs under grad: the slowest fit of the quick tier, so in the full suite
    pytest.param("orca", OrcaParams(time_horizon=2.0), "time_horizon", 5.0, 2.0, 1,
                 marks=pytest.mark.slow),
], ids=["hsfm_tau", "orca_time_horizon"])
def test_a_fit_recovers_the_headed_and_orca_constants_of_a_simulated_crowd(
        tmp_path, model, truth, name, start, goal, rows):
    """Tracks walked by the headed model (relaxation time 1 s) or by ORCA (time horizon 2 s):
    a fit of that constant alone from sgjax's default lowers the loss and moves the constant
    at least halfway to the truth (a broken or NaN gradient leaves it where it started). The
    headed model is fitted on the whole 12-row forecast: a restart from a recorded row cannot
    know its heading and turn rate, which bias a one-row fit of tracks it walked itself."""
    windows = _walked_by(truth, model, tmp_path)
    fitted, history = fit_social_force([windows], DT, steps=60, names=(name,), model=model,
                                       rows=rows)
    assert np.all(np.isfinite(history)) and history[-1] < 0.5 * history[0]
    assert abs(float(getattr(fitted, name)) - goal) < abs(start - goal) / 2


def test_short_rollouts_walk_several_rows_from_each_recorded_row(tmp_path):
    """The rollout loss of one row is the one-row loss; over several rows the model's own
    errors compound (the published constants on tracks walked with others lose more per row
    over four rows than over one), and the constants that walked the tracks lose almost nothing
(a restart from a recorded row knows the velocity only as the recorded step)."""
    truth = SocialForceParams(tau=1.2)
    windows = _walked_by(truth, "moussaid", tmp_path)
    published = SocialForceParams()
    assert float(rollout_loss(published, windows, DT, 1)) == pytest.approx(
        float(one_row_loss(published, windows, DT)), rel=1e-6)
    assert float(rollout_loss(published, windows, DT, 4)) > float(
        rollout_loss(published, windows, DT, 1))
    assert float(rollout_loss(truth, windows, DT, 4)) < 0.05 * float(
        rollout_loss(published, windows, DT, 4))
    with pytest.raises(ValueError, match="rows 13"):
        rollout_loss(published, windows, DT, 13)


def test_a_fit_goes_on_to_rollouts_and_helbing_rows_carry_trajnet_constants(tmp_path):
    """``--rollout-steps``: the row records the rollout phase; a Helbing row scores
    TrajNet++'s hand-tuned constants beside the published ones, with its paired difference,
    and the result still validates against the schema."""
    data = tmp_path / "data"
    data.mkdir()
    for k, stem in enumerate(("walk_a", "walk_b")):
        crowd(data / f"{stem}.txt", k)
    main(["crowd", "fit", "--model", "helbing", "--data", str(data), "--test", "walk_b",
          "--train", "walk_a", "--steps", "2", "--rollout-steps", "2", "--rollout-rows", "3",
          "--out", str(tmp_path / "out")])
    result = json.loads((tmp_path / "out" / "crowd_fit.json").read_text())
    jsonschema.validate(result, schema_for(result))
    row = result["rows"][0]
    assert row["rollout"]["rows"] == 3 and row["rollout"]["steps"] == 2
    assert row["trajnet"] == pytest.approx({"tau": 0.5, "v0": 2.1, "sigma": 0.3,
                                            "ellipse_dt": 0.05})
    assert {"trajnet", "published", "constant_velocity"} <= set(row["fitted_minus"])
    assert row["scores"]["trajnet"]["pedestrians"] > 0
    assert "| helbing | walk_b |" in (tmp_path / "out" / "crowd_fit.md").read_text()


def test_leave_one_scene_out_keeps_each_finished_scene_and_continues_after_them(
        tmp_path, monkeypatch):
    """A run stopped after two scenes keeps them in ``crowd_fit.partial.json``; the same
    command fits the other three alone and returns the kept rows as they were written; other
    settings are refused by name. (The bookkeeping alone: each scene's fit is a stand-in row
    here, the real fit is tested above.)"""
    from sgjax.evaluation import crowd_fit

    data = tmp_path / "data"
    fitted, stopped = [], []

    def stopping(model, data, scene, **kw):  # the first run stops after two scenes
        if len(fitted) == 2 and not stopped:
            stopped.append(scene)
            raise KeyboardInterrupt
        fitted.append(scene)
        score = {"ade": 0.1 * len(fitted), "fde": 0.2}
        return {"test": crowd_fit.SCENES[scene], "fit_seconds": 1.0, "steps": kw["steps"],
                "scores": {"fitted": score, "published": score, "constant_velocity": score}}

    monkeypatch.setattr(crowd_fit, "fit_scene", stopping)
    with pytest.raises(KeyboardInterrupt):
        crowd_fit.loso("moussaid", data, steps=2, log=lambda _: None, out=tmp_path / "out")
    kept = json.loads((tmp_path / "out" / crowd_fit.PARTIAL).read_text())["rows"]
    assert list(kept) == ["ETH", "HOTEL"]
    rows = crowd_fit.loso("moussaid", data, steps=2, log=lambda _: None, out=tmp_path / "out")
    assert fitted == list(crowd_fit.SCENES) and [r["test"] for r in rows] == list(
        crowd_fit.SCENES.values())
    assert [r["scores"]["fitted"]["ade"] for r in rows] == pytest.approx([0.1, 0.2, 0.3, 0.4, 0.5])
    with pytest.raises(ValueError, match="made with other settings"):
        crowd_fit.loso("moussaid", data, steps=3, log=lambda _: None, out=tmp_path / "out")
