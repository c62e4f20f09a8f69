"""Constants fitted to recorded people as presets (``human_constants``,
``sgjax.humans.calibrated``): the preset is the fit's file, ``make`` puts it in the params of
the law it was fitted for (and nowhere else), and a law without a fit or an unknown preset is
refused by name."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import sgjax
from sgjax.humans import calibrated
from sgjax.humans.calibrated import CALIBRATED, PARAMS_FIELD, fitted_constants

RESULTS = Path(__file__).resolve().parents[2] / "docs" / "results" / "calibration"
LAWS = sorted(CALIBRATED["eth_ucy"])


@pytest.mark.parametrize("model", LAWS)
def test_the_eth_ucy_preset_is_the_published_fit(model):
    fit = json.loads((RESULTS / f"all_{model}" / "crowd_fit.json").read_text())["rows"][0]
    assert fit["model"] == model and len(fit["train"]) == 5 and fit["test"] is None
    preset = CALIBRATED["eth_ucy"][model]
    assert set(preset) == set(fit["constants"])
    for name, value in fit["constants"].items():
        assert preset[name] == pytest.approx(value, rel=1e-3)


@pytest.mark.parametrize("model", LAWS)
def test_make_puts_the_preset_in_the_params_of_its_law_alone(model):
    _, params = sgjax.make("open", num_agents=2, num_humans=4, human_model=model,
                           human_constants="eth_ucy")
    _, published = sgjax.make("open", num_agents=2, num_humans=4, human_model=model)
    field = PARAMS_FIELD[model]
    for name, value in CALIBRATED["eth_ucy"][model].items():
        assert float(getattr(getattr(params.humans, field), name)) == pytest.approx(value)
        assert float(getattr(getattr(published.humans, field), name)) != pytest.approx(value)
    for other in {"forces", "hsfm", "orca"} - {field}:  # other laws' constants untouched
        assert getattr(params.humans, other) == getattr(published.humans, other)


def test_a_law_without_a_fit_or_an_unknown_preset_is_refused(monkeypatch):
    monkeypatch.setitem(CALIBRATED, "eth_ucy", {"moussaid": CALIBRATED["eth_ucy"]["moussaid"]})
    with pytest.raises(ValueError, match="not for human_model='orca': its time horizon has no"):
        sgjax.make("open", num_agents=2, num_humans=4, human_model="orca",
                   human_constants="eth_ucy")  # and why
    with pytest.raises(ValueError, match=r"not for human_model='helbing'$"):
        sgjax.make("open", num_agents=2, num_humans=4, human_model="helbing",
                   human_constants="eth_ucy")
    with pytest.raises(ValueError, match="human_constants"):
        sgjax.make("open", num_agents=2, num_humans=4, human_constants="eth-ucy")
    assert fitted_constants("published", "hsfm") == {}
    assert calibrated.with_constants("anything", "published", "hsfm") == "anything"


@pytest.mark.slow
def test_sgjax_evaluate_takes_the_preset_and_refuses_a_law_without_one(tmp_path, capsys,
                                                                      monkeypatch):
    from sgjax.command import main

    main(["evaluate", "--scenario", "hallway", "--policy", "only_local", "--num-agents", "2",
          "--num-humans", "4", "--human-model", "hsfm", "--human-constants", "eth_ucy",
          "--episodes", "2", "--time-limit", "3", "--out", str(tmp_path)])
    assert "hallway" in capsys.readouterr().out
    # the result file says which constants (and every other make option) it was played in
    played_in = json.loads((tmp_path / "metrics.json").read_text())["results"][0]["options"]
    assert played_in["humans"]["human_constants"] == "eth_ucy"
    assert played_in["humans"]["human_model"] == "hsfm"
    assert played_in["humans"]["num_humans"] == 4
    assert played_in["physics"]["time_limit"] == 3.0
    monkeypatch.setitem(CALIBRATED, "eth_ucy", {"moussaid": CALIBRATED["eth_ucy"]["moussaid"]})
    with pytest.raises(SystemExit, match="not for human_model='hsfm'"):
        main(["evaluate", "--scenario", "hallway", "--policy", "only_local", "--num-agents",
              "2", "--num-humans", "4", "--human-model", "hsfm", "--human-constants",
              "eth_ucy", "--episodes", "2"])
