"""Leave one ETH/UCY scene out: the Moussaid constants fitted on four scenes' windows (every
4th), scored on every window of the fifth beside constant velocity and the published constants.
Prints one JSON line per held-out scene (loso_moussaid.jsonl is its output).

    python docs/results-in-progress/calibration/loso_moussaid.py > loso_moussaid.jsonl
"""

import json

import jax

from sgjax.evaluation.calibration import FITTED, fit_social_force
from sgjax.evaluation.force_forecast import social_force_forecast
from sgjax.evaluation.forecasting import constant_velocity, forecast_windows, score_forecast
from sgjax.humans.forces import SocialForceParams
from sgjax.humans.tracks import read_tracks

SCENES = {"ETH": "biwi_eth", "HOTEL": "biwi_hotel", "UNIV": "students001",
          "ZARA1": "crowds_zara01", "ZARA2": "crowds_zara02"}
DT = 0.4


def scores(s) -> list[float]:
    return [float(s.ade), float(s.fde), float(s.collisions)]


def main() -> None:
    tracks = {s: read_tracks(f"../shared/pedestrians/eth_ucy/{f}.txt") for s, f in SCENES.items()}
    training = {s: forecast_windows(t, stride=4) for s, t in tracks.items()}
    moussaid = jax.jit(lambda p, w: score_forecast(*social_force_forecast(p, w, DT), w))
    for held in SCENES:
        fitted, history = fit_social_force([training[s] for s in SCENES if s != held], DT,
                                           steps=100)
        windows = forecast_windows(tracks[held])
        row = {"scene": held, "loss": [history[0], history[-1]],
               "constants": {k: round(float(getattr(fitted, k)), 3) for k in FITTED},
               "cv": scores(score_forecast(*constant_velocity(windows), windows)),
               "published": scores(moussaid(SocialForceParams(), windows)),
               "fitted": scores(moussaid(fitted, windows))}
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
