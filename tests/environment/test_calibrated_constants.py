"""Force constants fitted to recorded people as presets (``human_constants``,
``sgjax.humans.calibrated``): the preset is the fit's file, ``make`` puts it in the params of
the law it was fitted for, and a law without a fit or an unknown preset is refused by name."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import sgjax
from sgjax.humans.calibrated import CALIBRATED, force_constants
from sgjax.humans.forces import SocialForceParams

RESULTS = Path(__file__).resolve().parents[2] / "docs" / "results" / "calibration"


@pytest.mark.parametrize("model", ["moussaid", "helbing"])
def test_the_eth_ucy_preset_is_the_published_fit(model):
    fit = json.loads((RESULTS / f"all_{model}" / "crowd_fit.json").read_text())["rows"][0]
    assert len(fit["train"]) == 5 and fit["test"] is None
    preset = CALIBRATED["eth_ucy"][model]
    assert set(preset) == set(fit["constants"])
    for name, value in fit["constants"].items():
        assert preset[name] == pytest.approx(value, rel=1e-3)


@pytest.mark.parametrize("model", ["moussaid", "helbing"])
def test_make_puts_the_preset_in_the_params(model):
    _, params = sgjax.make("open", num_agents=2, num_humans=4, human_model=model,
                           human_constants="eth_ucy")
    forces = params.humans.forces
    for name, value in CALIBRATED["eth_ucy"][model].items():
        assert float(getattr(forces, name)) == pytest.approx(value)
    _, published = sgjax.make("open", num_agents=2, num_humans=4, human_model=model)
    assert published.humans.forces == SocialForceParams()


def test_a_law_without_a_fit_or_an_unknown_preset_is_refused():
    with pytest.raises(ValueError, match="not for human_model='orca'"):
        sgjax.make("open", num_agents=2, num_humans=4, human_model="orca",
                   human_constants="eth_ucy")
    with pytest.raises(ValueError, match="human_constants"):
        sgjax.make("open", num_agents=2, num_humans=4, human_constants="eth-ucy")
    assert force_constants("published", "hsfm") == SocialForceParams()
