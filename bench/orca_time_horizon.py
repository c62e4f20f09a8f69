"""ORCA's one fitted constant against recorded people: the one-row loss of every ETH/UCY scene
along a range of time horizons.

``sgjax crowd fit --model orca`` fits one constant, the time horizon (s), by Adam on its
logarithm. This prints the teacher-forced one-row loss (m^2, the loss the fit minimises:
``sgjax.evaluation.force_forecast.one_row_loss``, the fit's training windows) of each scene and
their mean at each ``--horizons`` value, so that one can see whether a fit's end point is a
minimum or where it stopped on a slope.

    python bench/orca_time_horizon.py --data ../shared/pedestrians/eth_ucy
    python bench/orca_time_horizon.py --data DIR --horizons 5 10 20 40 80 160 320

Forward passes only (no gradient): a few minutes on a 2-core CPU, most of it compiling one
loss per scene and UNIV's 57-person windows.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path

import jax
import jax.numpy as jnp

from sgjax.evaluation.crowd_fit import ROW_SECONDS, SCENES, TRAIN_STRIDE, scene_path
from sgjax.evaluation.force_forecast import default_constants, one_row_loss
from sgjax.evaluation.forecasting import forecast_windows
from sgjax.humans.tracks import read_tracks


def profile(data: Path, scenes: Sequence[str], horizons: Sequence[float]
            ) -> list[tuple[float, list[float]]]:
    """``[(horizon s, [one-row loss m^2 per scene])]`` at each of ``horizons``."""
    windows = [forecast_windows(read_tracks(scene_path(data, s)), stride=TRAIN_STRIDE)
               for s in scenes]
    losses = [jax.jit(lambda p, w=w: one_row_loss(p, w, ROW_SECONDS, model="orca"))
              for w in windows]
    start = default_constants("orca")
    rows = []
    for horizon in horizons:
        params = start.replace(time_horizon=jnp.float32(horizon))
        rows.append((float(horizon), [float(loss(params)) for loss in losses]))
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", required=True, help="the ETH/UCY folder")
    parser.add_argument("--scenes", nargs="+", default=list(SCENES), choices=SCENES)
    parser.add_argument("--horizons", nargs="+", type=float,
                        default=[5.0, 15.0, 30.0, 60.0, 100.0, 300.0],
                        help="time horizons (s) to score")
    args = parser.parse_args(argv)
    if any(h <= 0 for h in args.horizons):
        parser.error("--horizons must be positive")
    t0 = time.perf_counter()
    rows = profile(Path(args.data), args.scenes, args.horizons)
    print("| time horizon (s) | " + " | ".join(args.scenes) + " | mean |")
    print("|---:|" + "---:|" * (len(args.scenes) + 1))
    for horizon, values in rows:
        cells = " | ".join(f"{v:.5f}" for v in values)
        print(f"| {horizon:g} | {cells} | {sum(values) / len(values):.5f} |")
    print(f"({time.perf_counter() - t0:.0f} s, jax {jax.__version__}, "
          f"{jax.devices()[0].platform})")


if __name__ == "__main__":
    main()
