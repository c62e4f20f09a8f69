"""Pedestrian constants fitted to recorded people, shipped as presets
(``sgjax.make(..., human_constants="eth_ucy")``; ``"published"``, the default, keeps the laws'
published constants).

``eth_ucy``: each law's interaction and relaxation constants fitted by gradient on all five
standard ETH/UCY scenes (ETH, HOTEL, UNIV, ZARA1, ZARA2; ``sgjax crowd fit --model M --data
../shared/pedestrians/eth_ucy --train ETH HOTEL UNIV ZARA1 ZARA2``, 100 Adam steps of the
teacher-forced one-row loss). The fits, their provenance and the leave-one-scene-out scores
that say how well such a fit forecasts a scene it never saw are in
``docs/results/calibration/`` (docs/results.md). Only the social-force laws are calibrated;
the other constants (desired speeds, walls, ORCA, HSFM) stay as published."""

from __future__ import annotations

from sgjax.humans.forces import SocialForceParams

# law -> fitted constants, per preset (docs/results/calibration/all_<law>/crowd_fit.json)
CALIBRATED: dict[str, dict[str, dict[str, float]]] = {
    "eth_ucy": {
        "moussaid": {"tau": 3.7228, "social_strength": 1.6773, "lambda_importance": 4.9889,
                     "gamma": 0.1041, "n": 7.1866, "n_prime": 6.464},
        "helbing": {"tau": 3.7088, "v0": 0.4724, "sigma": 0.0617, "ellipse_dt": 0.5773},
    },
}
CONSTANT_SETS = ("published", *CALIBRATED)


def force_constants(name: str, model: str) -> SocialForceParams:
    """The social-force constants of preset ``name`` for the ``model`` law (the published
    ones for ``"published"``); an error names a preset without that law."""
    if name == "published":
        return SocialForceParams()
    if name not in CALIBRATED:
        raise ValueError(f"human_constants must be one of {CONSTANT_SETS}, got {name!r}")
    fitted = CALIBRATED[name]
    if model not in fitted:
        raise ValueError(f"human_constants={name!r} holds constants fitted for "
                         f"{', '.join(fitted)}, not for human_model={model!r}")
    return SocialForceParams(**fitted[model])
