"""Leave one ETH/UCY scene out: the Moussaid constants fitted on four scenes' windows (every
4th), scored on every window of the fifth beside constant velocity and the published constants.
Prints one JSON line per held-out scene (loso_moussaid.jsonl is its output).

    python docs/results-in-progress/calibration/loso_moussaid.py > loso_moussaid.jsonl
    python docs/results-in-progress/calibration/loso_moussaid.py --table loso_moussaid.jsonl

(the second prints docs/humans.md's table from the output)
"""

import json
import sys
from pathlib import Path

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


def table(path: str) -> str:
    """docs/humans.md's leave-one-scene-out table, from the output lines at ``path``."""
    lines = ["| held-out scene | constant velocity ADE / FDE (m) | Moussaid, published | "
             "Moussaid, fitted on the other four | fitted: tau (s), A (m/s^2), lambda, gamma, "
             "n, n' |", "|---|---|---|---|---|"]
    for text in Path(path).read_text().splitlines():
        row = json.loads(text)
        c = row["constants"]
        cell = lambda v: f"{v[0]:.3f} / {v[1]:.3f}, {100 * v[2]:.1f}%"  # noqa: E731
        lines.append(f"| {row['scene']} | {cell(row['cv'])} | {cell(row['published'])} | "
                     f"{cell(row['fitted'])} | {c['tau']}, {c['social_strength']}, "
                     f"{c['lambda_importance']}, {c['gamma']}, {c['n']}, {c['n_prime']} |")
    return "\n".join(lines)


def main() -> None:
    if sys.argv[1:2] == ["--table"]:
        print(table(sys.argv[2]))
        return
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
