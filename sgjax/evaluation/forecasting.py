"""Forecasts of recorded pedestrians scored as the trajectory-forecasting literature scores
them: observe 8 rows (3.2 s at ETH/UCY's 0.4 s), predict 12 (4.8 s), average and final
displacement error (ADE, FDE, m) over the pedestrians present in all 20 rows of a window, and
the share of predicted pedestrians that come closer to another predicted one than two
TrajNet++ person radii (0.1 m each), checked at each predicted row and half-way between rows.

The constant-velocity forecast (the last observed velocity, held) is the floor every model is
compared with; the windows come from :func:`sgjax.humans.tracks.track_windows` and every
function here works on a batch of them (``[N, ...]`` arrays), inside ``jit``."""

from __future__ import annotations

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.humans.tracks import Tracks, TrackWindows, track_windows

OBSERVE, PREDICT = 8, 12  # rows observed and predicted (the standard ETH/UCY protocol)
PERSON_RADIUS = 0.1  # m: TrajNet++'s collision radius of a predicted pedestrian


@struct.dataclass
class ForecastScores:
    """Scores of a batch of forecasts (means over the scored pedestrians of every window): ADE
    and FDE (m), the share of pedestrians in a predicted collision, and how many pedestrians
    were scored."""

    ade: Array
    fde: Array
    collisions: Array
    pedestrians: Array


def forecast_windows(tracks: Tracks, observe: int = OBSERVE, predict: int = PREDICT,
                     stride: int = 1) -> TrackWindows:
    """Every window of ``observe + predict`` rows (one every ``stride`` rows) with the
    pedestrians present in all of its rows (the protocol's fully observed tracks)."""
    return track_windows(tracks, observe + predict, stride, whole=True)


def constant_velocity(windows: TrackWindows, observe: int = OBSERVE) -> tuple[Array, Array]:
    """``(x, y) [N, P, Pw]`` (m): each pedestrian's last observed step (row ``observe - 1``
    minus row ``observe - 2``) repeated over the ``P`` rows after the observation."""
    predict = windows.x.shape[1] - observe
    steps = jnp.arange(1, predict + 1, dtype=jnp.float32)[None, :, None]

    def held(z: Array) -> Array:
        last, before = z[:, observe - 1], z[:, observe - 2]
        return last[:, None] + steps * (last - before)[:, None]

    return held(windows.x), held(windows.y)


def scored(windows: TrackWindows) -> Array:
    """``[N, Pw]`` bool: the pedestrians a forecast is scored on (present in every row)."""
    return jnp.all(windows.valid, axis=1) & (windows.ids >= 0)


def displacement_errors(x: Array, y: Array, windows: TrackWindows, observe: int = OBSERVE
                        ) -> tuple[Array, Array]:
    """``(ade, fde) [N, Pw]`` (m) of forecasts ``x, y [N, P, Pw]`` against the recorded rows
    after the observation (0 for pedestrians not scored)."""
    error = jnp.hypot(x - windows.x[:, observe:], y - windows.y[:, observe:])  # [N, P, Pw]
    keep = scored(windows)
    return (jnp.where(keep, jnp.mean(error, axis=1), 0.0),
            jnp.where(keep, error[:, -1], 0.0))


def predicted_collisions(x: Array, y: Array, keep: Array, radius: float = PERSON_RADIUS
                         ) -> Array:
    """``[N, Pw]`` bool: the scored pedestrians (``keep [N, Pw]``) whose forecast ``x, y [N, P,
    Pw]`` comes within ``2 radius`` of another scored pedestrian's at a predicted row or
    half-way between two."""
    half_x, half_y = (x[:, 1:] + x[:, :-1]) / 2, (y[:, 1:] + y[:, :-1]) / 2
    px, py = jnp.concatenate([x, half_x], axis=1), jnp.concatenate([y, half_y], axis=1)
    gap = jnp.hypot(px[..., :, None] - px[..., None, :], py[..., :, None] - py[..., None, :])
    width = keep.shape[-1]
    pair = keep[:, None, :, None] & keep[:, None, None, :] & ~jnp.eye(width, dtype=bool)
    return keep & jnp.any(pair & (gap < 2.0 * radius), axis=(1, 3))


def score_forecast(x: Array, y: Array, windows: TrackWindows, observe: int = OBSERVE
                   ) -> ForecastScores:
    """ADE, FDE and the collision share of forecasts ``x, y [N, P, Pw]`` over every scored
    pedestrian of every window."""
    keep = scored(windows)
    ade, fde = displacement_errors(x, y, windows, observe)
    count = jnp.maximum(jnp.sum(keep), 1)
    hit = predicted_collisions(x, y, keep)
    return ForecastScores(ade=jnp.sum(ade) / count, fde=jnp.sum(fde) / count,
                          collisions=jnp.sum(hit) / count, pedestrians=jnp.sum(keep))
