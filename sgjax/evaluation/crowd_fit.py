"""``sgjax crowd fit`` and ``sgjax crowd loso``: a pedestrian model calibrated to recorded
people, scored on a held-out scene as the forecasting literature scores it, written as a result
file with its provenance (issue 68).

A fit (:func:`fit_scene`) reads the training scenes' tracks (every 4th window of 8 observed +
12 predicted rows), fits the model's constants by gradient
(:func:`sgjax.evaluation.calibration.fit_social_force`): first on the teacher-forced one-row
loss, then (``rollout_steps``) on short rollouts of ``rollout_rows`` rows from the first fit.
It forecasts every window of the held-out scene with the constant-velocity floor, the model's
published (sgjax's default) constants, TrajNet++'s hand-tuned ones where the model has them
(Helbing and Molnar's potentials) and the fitted ones: ADE and FDE (m) and the share of
pedestrians in a predicted collision. Differences come
with 95% paired t intervals over the held-out scene's non-overlapping windows (20 rows, 8 s
apart: consecutive windows share 19 of 20 rows, so intervals over all of them would count one
walk twenty times). ``loso`` runs the five standard scenes (ETH, HOTEL, UNIV, ZARA1, ZARA2),
each held out once. The data folder is the user's (``../shared/pedestrians/eth_ucy`` here):
nothing is downloaded."""

from __future__ import annotations

import json
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import jax
import numpy as np

from sgjax.evaluation.calibration import FITTED_BY_MODEL, TRAJNET_CONSTANTS, fit_social_force
from sgjax.evaluation.force_forecast import ModelParams, default_constants, social_force_forecast
from sgjax.evaluation.forecasting import (
    OBSERVE,
    PREDICT,
    constant_velocity,
    displacement_errors,
    forecast_windows,
    score_forecast,
    scored,
)
from sgjax.evaluation.provenance import provenance
from sgjax.evaluation.statistics import paired_difference
from sgjax.files import write_atomic
from sgjax.humans.tracks import TrackWindows, read_tracks

SCHEMA = "sgjax.crowd_fit/1"
# the five standard scenes of the ETH/UCY protocol, by the files that hold them
SCENES = {"ETH": "biwi_eth", "HOTEL": "biwi_hotel", "UNIV": "students001",
          "ZARA1": "crowds_zara01", "ZARA2": "crowds_zara02"}
ROW_SECONDS = 0.4  # s between ETH/UCY rows
TRAIN_STRIDE = 4  # rows between two training windows
BLOCK = OBSERVE + PREDICT  # rows between two windows of the intervals (no shared rows)


def scene_path(data: Path, scene: str) -> Path:
    """The track file of ``scene``: a standard scene's name (``ZARA1``), a file stem
    (``crowds_zara01``) or a file name, in the folder ``data``; an error names what is
    missing."""
    stem = SCENES.get(scene.upper(), Path(scene).stem)
    path = data / f"{stem}.txt"
    if not path.is_file():
        raise ValueError(f"--data {data}: no track file {path.name} for scene {scene!r} "
                         f"(standard scenes: {', '.join(SCENES)})")
    return path


def _scores(score: Any) -> dict[str, float]:
    return {"ade": float(score.ade), "fde": float(score.fde),
            "collisions": float(score.collisions), "pedestrians": int(score.pedestrians)}


def _window_ade(x: Any, y: Any, windows: TrackWindows) -> np.ndarray:
    """``[N]``: each window's mean ADE (m) over its scored pedestrians."""
    ade, _ = displacement_errors(x, y, windows)
    count = np.maximum(np.asarray(scored(windows)).sum(axis=1), 1)
    return np.asarray(ade).sum(axis=1) / count


def _difference(a: np.ndarray, b: np.ndarray) -> dict[str, float]:
    d = paired_difference(a, b)
    return {"mean": d.mean, "ci_low": d.ci_low, "ci_high": d.ci_high, "windows": d.n}


ROLLOUT_ROWS = 4  # rows (1.6 s) of the short rollouts after the one-row fit


def _constants(model: str, p: ModelParams) -> dict[str, float]:
    return {k: float(getattr(p, k)) for k in FITTED_BY_MODEL[model]}


def fit_scene(model: str, data: Path, test: str | None, train: Sequence[str] | None = None,
              steps: int = 100, max_seconds: float | None = None, rollout_steps: int = 0,
              rollout_rows: int = ROLLOUT_ROWS) -> dict[str, Any]:
    """One fit of ``model`` on the ``train`` scenes (default: the standard five but ``test``):
    ``steps`` on the one-row loss, then ``rollout_steps`` on rollouts of ``rollout_rows`` rows
    (``max_seconds`` bounds each phase); its scores on ``test`` (None: fit only). Returns the
    result row (module doc)."""
    test_path = None if test is None else scene_path(data, test)
    if train is None:
        train = [s for s in SCENES if test_path is None or SCENES[s] != test_path.stem]
    if not train:
        raise ValueError("no training scene left: give --train")
    began = time.perf_counter()
    windows = [forecast_windows(read_tracks(scene_path(data, s)), stride=TRAIN_STRIDE)
               for s in train]
    fitted, history = fit_social_force(windows, ROW_SECONDS, steps=steps, model=model,
                                       max_seconds=max_seconds)
    rollout: list[float] = []
    if rollout_steps > 0:
        fitted, rollout = fit_social_force(windows, ROW_SECONDS, steps=rollout_steps,
                                           model=model, max_seconds=max_seconds, start=fitted,
                                           rows=rollout_rows)
    row: dict[str, Any] = {
        "model": model, "train": [scene_path(data, s).stem for s in train],
        "test": None if test_path is None else test_path.stem,
        "steps": len(history), "loss": {"first": history[0], "last": history[-1]},
        "constants": _constants(model, fitted),
        "published": _constants(model, default_constants(model)),
        "fit_seconds": round(time.perf_counter() - began, 1),
    }
    if rollout:
        row["rollout"] = {"rows": rollout_rows, "steps": len(rollout),
                          "loss": {"first": rollout[0], "last": rollout[-1]}}
    if model in TRAJNET_CONSTANTS:
        row["trajnet"] = _constants(model, TRAJNET_CONSTANTS[model])
    if test_path is not None:
        row.update(score_scene(model, fitted, test_path))
    return row


def score_scene(model: str, fitted: ModelParams, path: Path) -> dict[str, Any]:
    """Constant velocity, the published, TrajNet++'s (where the model has them) and the fitted
    constants on every window of the track file ``path``, and the fitted model's paired
    differences over its non-overlapping windows."""
    tracks = read_tracks(path)
    law = jax.jit(lambda p, w: social_force_forecast(p, w, ROW_SECONDS, model=model))
    others = {"published": default_constants(model)}
    if model in TRAJNET_CONSTANTS:
        others["trajnet"] = TRAJNET_CONSTANTS[model]
    out: dict[str, Any] = {}
    for key, stride in (("scores", 1), ("blocks", BLOCK)):
        windows = forecast_windows(tracks, stride=stride)
        forecasts = {"constant_velocity": constant_velocity(windows),
                     **{name: law(p, windows) for name, p in others.items()},
                     "fitted": law(fitted, windows)}
        if key == "scores":
            out[key] = {name: _scores(score_forecast(*xy, windows))
                        for name, xy in forecasts.items()}
        else:
            ade = {name: _window_ade(*xy, windows) for name, xy in forecasts.items()}
            out["fitted_minus"] = {name: _difference(ade["fitted"], ade[name])
                                   for name in forecasts if name != "fitted"}
    return out


def write_result(out: Path, rows: list[dict[str, Any]], seconds: Mapping[str, float]) -> Path:
    """``out/crowd_fit.json`` (rows and provenance) and ``out/crowd_fit.md`` (its table)."""
    result = {"schema_version": SCHEMA, "provenance": provenance(
        config={"rows": [{k: r[k] for k in ("model", "train", "test", "steps")} for r in rows]},
        seconds=seconds), "row_seconds": ROW_SECONDS, "observe": OBSERVE, "predict": PREDICT,
        "rows": rows}
    out.mkdir(parents=True, exist_ok=True)
    path = write_atomic(out / "crowd_fit.json", json.dumps(result, indent=1) + "\n")
    write_atomic(out / "crowd_fit.md", table(result) + "\n")
    return path


def table(result: Mapping[str, Any]) -> str:
    """The fidelity table of a result: per held-out scene, ADE / FDE (m) and the predicted
    collision share of constant velocity, the published and the fitted constants, the fitted
    law's ADE difference with each (paired interval over non-overlapping windows), and the
    fitted constants."""
    lines = ["| model | held-out scene | constant velocity | published | TrajNet++ | fitted on "
             "the others | fitted - published ADE (m) | fitted - TrajNet++ ADE (m) | fitted - "
             "constant velocity ADE (m) | fitted constants |",
             "|---|---|---|---|---|---|---|---|---|---|"]

    def cell(s: Mapping[str, float]) -> str:
        return f"{s['ade']:.3f} / {s['fde']:.3f}, {100 * s['collisions']:.1f}%"

    def diff(d: Mapping[str, float]) -> str:
        return f"{d['mean']:+.3f} [{d['ci_low']:+.3f}, {d['ci_high']:+.3f}]"

    for row in result["rows"]:
        if row.get("test") is None:
            continue
        s, d = row["scores"], row["fitted_minus"]
        constants = ", ".join(f"{k} {v:.3g}" for k, v in row["constants"].items())
        trajnet = "trajnet" in s
        lines.append(f"| {row['model']} | {row['test']} | {cell(s['constant_velocity'])} | "
                     f"{cell(s['published'])} | "
                     f"{cell(s['trajnet']) if trajnet else '-'} | {cell(s['fitted'])} | "
                     f"{diff(d['published'])} | {diff(d['trajnet']) if trajnet else '-'} | "
                     f"{diff(d['constant_velocity'])} | {constants} |")
    return "\n".join(lines)


PARTIAL = "crowd_fit.partial.json"  # a leave-one-scene-out run's finished scenes


def loso(model: str, data: Path, steps: int = 100, max_seconds: float | None = None,
         log: Any = print, rollout_steps: int = 0, rollout_rows: int = ROLLOUT_ROWS,
         out: Path | None = None) -> list[dict[str, Any]]:
    """Leave one scene out over the standard five: a row per held-out scene. With ``out``,
    each finished scene's row is kept in ``out/`` :data:`PARTIAL` (with the run's settings)
    and a later call with the same settings continues after them (a fit of the headed model
    or ORCA takes up to 20 minutes; a stopped machine loses the scene it was fitting)."""
    settings = {"model": model, "steps": steps, "max_seconds": max_seconds,
                "rollout_steps": rollout_steps, "rollout_rows": rollout_rows}
    kept: dict[str, Any] = {}
    partial = None if out is None else out / PARTIAL
    if partial is not None and partial.is_file():
        earlier = json.loads(partial.read_text())
        if earlier.get("settings") != settings:
            raise ValueError(f"{partial}: made with other settings ({earlier.get('settings')}); "
                             "delete it to start again")
        kept = earlier["rows"]
        log(f"{model}: {len(kept)} scene(s) kept from {partial}")
    rows = []
    for scene in SCENES:
        if scene in kept:
            rows.append(kept[scene])
            continue
        row = fit_scene(model, data, scene, steps=steps, max_seconds=max_seconds,
                        rollout_steps=rollout_steps, rollout_rows=rollout_rows)
        if partial is not None:
            kept[scene] = row
            partial.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(partial, json.dumps({"settings": settings, "rows": kept}) + "\n")
        log(f"{model}, {scene} held out: fitted in {row['fit_seconds']} s ({row['steps']} "
            f"steps); ADE fitted {row['scores']['fitted']['ade']:.3f} m, published "
            f"{row['scores']['published']['ade']:.3f}, constant velocity "
            f"{row['scores']['constant_velocity']['ade']:.3f}")
        rows.append(row)
    return rows
