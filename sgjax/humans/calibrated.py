"""Pedestrian constants fitted to recorded people, shipped as presets
(``sgjax.make(..., human_constants="eth_ucy")``; ``"published"``, the default, keeps the laws'
published constants).

``eth_ucy``: each law's interaction and relaxation constants fitted by gradient on all five
standard ETH/UCY scenes (ETH, HOTEL, UNIV, ZARA1, ZARA2; ``sgjax crowd fit --model M --data
../shared/pedestrians/eth_ucy --train ETH HOTEL UNIV ZARA1 ZARA2``, 100 Adam steps of the
teacher-forced one-row loss): Moussaid's and Helbing's social forces (``params.humans.forces``),
and the headed social force model's driving, interaction and turning constants
(``params.humans.hsfm``; its contact stiffness and friction stay as published: recorded people
avoid contact). ORCA has none: its one fitted constant, the time horizon, has no finite
optimum on these recordings (the one-row loss falls in every scene up to a 1,000 s horizon:
``bench/orca_time_horizon.py``, docs/results.md), so a preset would name wherever a fit
stopped; ``human_constants="eth_ucy"`` with ``human_model="orca"`` is an error. The fits,
their provenance and the leave-one-scene-out scores that say how well such a fit forecasts a
scene it never saw are in ``docs/results/calibration/`` (docs/results.md). The other constants
(desired speeds, walls) stay as published."""

from __future__ import annotations

from typing import Any

# law -> fitted constants, per preset (docs/results/calibration/all_<law>/crowd_fit.json)
CALIBRATED: dict[str, dict[str, dict[str, float]]] = {
    "eth_ucy": {
        "moussaid": {"tau": 3.7228, "social_strength": 1.6773, "lambda_importance": 4.9889,
                     "gamma": 0.1041, "n": 7.1866, "n_prime": 6.464},
        "helbing": {"tau": 3.7088, "v0": 0.4724, "sigma": 0.0617, "ellipse_dt": 0.5773},
        "hsfm": {"tau": 2.618, "strength": 117.2, "falloff": 0.039451, "k_orthogonal": 1.4768,
                 "k_damping": 2117.9, "k_lambda": 0.042117},
    },
}
# preset -> law -> why it holds no constants for that law
NOT_FITTED: dict[str, dict[str, str]] = {
    "eth_ucy": {"orca": "its time horizon has no finite optimum on these recordings (the "
                        "one-row loss falls up to a 1,000 s horizon: bench/orca_time_horizon.py)"},
}
CONSTANT_SETS = ("published", *CALIBRATED)
# law -> the HumanParams field holding its constants
PARAMS_FIELD = {"moussaid": "forces", "helbing": "forces", "hsfm": "hsfm", "orca": "orca"}


def fitted_constants(name: str, model: str) -> dict[str, float]:
    """The constants preset ``name`` fitted for the ``model`` law (``{}`` for
    ``"published"``); an error names an unknown preset or a preset without that law."""
    if name == "published":
        return {}
    if name not in CALIBRATED:
        raise ValueError(f"human_constants must be one of {CONSTANT_SETS}, got {name!r}")
    fitted = CALIBRATED[name]
    if model not in fitted:
        why = NOT_FITTED.get(name, {}).get(model)
        raise ValueError(f"human_constants={name!r} holds constants fitted for "
                         f"{', '.join(fitted)}, not for human_model={model!r}"
                         + (f": {why}" if why else ""))
    return dict(fitted[model])


def with_constants(hp: Any, name: str, model: str) -> Any:
    """``hp`` (``HumanParams``) with preset ``name``'s constants for the ``model`` law in that
    law's params (:data:`PARAMS_FIELD`); unchanged for ``"published"``."""
    fitted = fitted_constants(name, model)
    if not fitted:
        return hp
    field = PARAMS_FIELD[model]
    return hp.replace(**{field: getattr(hp, field).replace(**fitted)})
