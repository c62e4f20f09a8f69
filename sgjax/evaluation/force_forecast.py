"""Recorded pedestrians forecast by sgjax's social forces (the Moussaid law or Helbing and
Molnar's potentials: ``model``), and the one-row loss that fits their constants to the
recordings by gradient (issue 68's calibration).

From the last observed row of a window (:func:`sgjax.evaluation.forecasting.forecast_windows`)
every scored pedestrian starts at its recorded position with its last recorded step as
velocity, wants to walk at its mean observed speed towards a goal: where its mean observed
velocity would take it by the end of the forecast (no oracle destination). The pedestrians of
a window meet each other through :func:`sgjax.humans.forces.moussaid_interaction` (or
:func:`~sgjax.humans.forces.helbing_interaction`, its field of view the desired direction); no
walls (the scenes' obstacles are not annotated). Each row of 0.4 s is ``substeps`` explicit
steps, integrated as the environment integrates its pedestrians (``v <- cap(v + h F)``,
``x <- x + h v``). Everything is a pure function of :class:`SocialForceParams`, so
``jax.grad`` fits them."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array

from sgjax.evaluation.forecasting import OBSERVE, scored
from sgjax.humans.forces import (
    SocialForceParams,
    cap_speed,
    desired_force,
    helbing_interaction,
    moussaid_interaction,
    unit,
)
from sgjax.humans.tracks import TrackWindows

SUBSTEPS = 4  # explicit steps per recorded row (0.1 s at ETH/UCY's 0.4 s)
MAX_SPEED_FACTOR = 1.3  # a pedestrian never walks faster than this times its own speed
# m/s: a pedestrian whose mean observed velocity is slower than this is standing (it wants to
# stay: desired speed 0). Its goal would lie on itself, where the direction to it turns with
# every millimetre and the loss's gradient in the constants reaches 1e7 (two waiting people in
# HOTEL did that).
STANDING = 0.1


MODELS = ("moussaid", "helbing")  # the laws a forecast walks (sgjax.humans.forces)


def _walk(p: SocialForceParams, x: Array, y: Array, vx: Array, vy: Array,
          intent: tuple[Array, Array, Array, Array], mask: Array, h: float,
          model: str = "moussaid") -> tuple[Array, ...]:
    """One explicit step of ``h`` s of pedestrians ``[P]`` (``mask``: the real ones) with
    their ``intent`` (:func:`intentions`)."""
    goal_x, goal_y, speed, top = intent
    fx, fy = desired_force(x, y, vx, vy, goal_x, goal_y, speed, p.tau)
    pair = (mask[:, None] & mask[None, :] & ~jnp.eye(mask.shape[0], dtype=bool))
    weight = pair.astype(jnp.float32)
    if model == "helbing":
        ex, ey, _ = unit(goal_x - x, goal_y - y)
        sx, sy = helbing_interaction(x, y, ex, ey, x, y, vx, vy, weight, p)
    else:
        sx, sy = moussaid_interaction(x, y, vx, vy, x, y, vx, vy, weight, p)
    vx, vy = cap_speed(vx + h * (fx + sx), vy + h * (fy + sy), top)
    return x + h * vx, y + h * vy, vx, vy


def intentions(windows: TrackWindows, dt: float, observe: int = OBSERVE
               ) -> tuple[Array, Array, Array, Array]:
    """``(goal_x, goal_y, speed, top) [N, Pw]``: each pedestrian's mean observed velocity
    carried from its last observed position over the forecast's length (m), its desired speed
    (its mean observed speed, m/s; 0 for one standing: mean observed velocity under
    :data:`STANDING`) and its top speed (:data:`MAX_SPEED_FACTOR` times its observed speed, at
    least 0.1 m/s)."""
    rows = windows.x.shape[1] - observe
    span = (observe - 1) * dt
    vx = (windows.x[:, observe - 1] - windows.x[:, 0]) / span
    vy = (windows.y[:, observe - 1] - windows.y[:, 0]) / span
    steps = jnp.hypot(jnp.diff(windows.x[:, :observe], axis=1),
                      jnp.diff(windows.y[:, :observe], axis=1))
    speed = jnp.mean(steps, axis=1) / dt
    standing = jnp.hypot(vx, vy) < STANDING
    return (windows.x[:, observe - 1] + vx * rows * dt,
            windows.y[:, observe - 1] + vy * rows * dt, jnp.where(standing, 0.0, speed),
            MAX_SPEED_FACTOR * jnp.maximum(speed, 0.1))


def _rows(p: SocialForceParams, start: tuple[Array, ...],
          intent: tuple[Array, Array, Array, Array], mask: Array, rows: int, dt: float,
          substeps: int, model: str = "moussaid") -> tuple[Array, Array]:
    """``(x, y) [rows, P]``: one window's pedestrians walked from ``start`` (x, y, vx, vy)."""
    h = dt / substeps

    def row(state: tuple[Array, ...], _: None) -> tuple[tuple[Array, ...], tuple[Array, Array]]:
        for _ in range(substeps):
            state = _walk(p, *state, intent, mask, h, model)
        return state, (state[0], state[1])

    return jax.lax.scan(row, start, None, length=rows)[1]


def social_force_forecast(p: SocialForceParams, windows: TrackWindows, dt: float,
                          observe: int = OBSERVE, substeps: int = SUBSTEPS,
                          model: str = "moussaid") -> tuple[Array, Array]:
    """``(x, y) [N, P, Pw]`` (m): every window's scored pedestrians walked by the ``model``
    law (:data:`MODELS`) from the last observed row over the ``P`` forecast rows (module
    doc)."""
    _check_model(model)
    rows = windows.x.shape[1] - observe
    intent = intentions(windows, dt, observe)
    mask = scored(windows)

    def one(x: Array, y: Array, intent: tuple[Array, ...], m: Array) -> tuple[Array, Array]:
        start = (x[observe - 1], y[observe - 1], (x[observe - 1] - x[observe - 2]) / dt,
                 (y[observe - 1] - y[observe - 2]) / dt)
        return _rows(p, start, intent, m, rows, dt, substeps, model)

    return jax.vmap(one)(windows.x, windows.y, intent, mask)


def one_row_loss(p: SocialForceParams, windows: TrackWindows, dt: float,
                 observe: int = OBSERVE, substeps: int = SUBSTEPS, model: str = "moussaid"
                 ) -> Array:
    """Mean squared error (m^2) of one row walked by the ``model`` law from each recorded row
    of the forecast part (teacher forcing: position and velocity from the recording, the
    intentions of :func:`intentions`) against the next recorded row, over every scored
    pedestrian."""
    _check_model(model)
    intent = intentions(windows, dt, observe)
    mask = scored(windows)
    last = windows.x.shape[1] - 1

    def one(x: Array, y: Array, intent: tuple[Array, ...], m: Array) -> Array:
        def at(k: Array) -> Array:
            start = (x[k], y[k], (x[k] - x[k - 1]) / dt, (y[k] - y[k - 1]) / dt)
            px, py = _rows(p, start, intent, m, 1, dt, substeps, model)
            error = jnp.square(px[0] - x[k + 1]) + jnp.square(py[0] - y[k + 1])
            return jnp.sum(jnp.where(m, error, 0.0))

        return jnp.sum(jax.vmap(at)(jnp.arange(observe - 1, last)))

    total = jnp.sum(jax.vmap(one)(windows.x, windows.y, intent, mask))
    return total / jnp.maximum(jnp.sum(mask) * (last - observe + 1), 1)


def _check_model(model: str) -> None:
    if model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
