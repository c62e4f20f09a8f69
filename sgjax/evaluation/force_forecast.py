"""Recorded pedestrians forecast by sgjax's pedestrian models (the Moussaid law, Helbing and
Molnar's potentials, the headed social force model or ORCA: ``model``), and the losses that fit
their constants to the recordings by gradient (issue 68's calibration).

From the last observed row of a window (:func:`sgjax.evaluation.forecasting.forecast_windows`)
every scored pedestrian starts at its recorded position with its last recorded step as
velocity (and, for the headed model, facing along it, not turning), wants to walk at its mean
observed speed towards a goal: where its mean observed velocity would take it by the end of the
forecast (no oracle destination). The pedestrians of a window meet each other through the
model's own interaction (:func:`sgjax.humans.forces.moussaid_interaction`,
:func:`~sgjax.humans.forces.helbing_interaction` with its field of view the desired direction,
:func:`sgjax.humans.hsfm.pair_force` and :func:`~sgjax.humans.hsfm.headed_step`, or
:func:`sgjax.kernels.orca.orca_velocity` among the :data:`ORCA_NEIGHBORS` nearest, each
pedestrian taking half the avoidance); no walls (the scenes' obstacles are not annotated).
Each row of 0.4 s is :data:`SUBSTEPS` explicit steps (the headed model's stiff contact terms:
:data:`HSFM_SUBSTEPS`), integrated as the environment integrates its pedestrians
(``v <- cap(v + h F)``, ``x <- x + h v``; an ORCA pedestrian takes its ORCA velocity). The
headed and ORCA pedestrians have the environment's default radius (:data:`RADIUS`).
Everything is a pure function of the model's constants (:class:`SocialForceParams`,
:class:`HsfmParams`, :class:`OrcaParams`), so ``jax.grad`` fits them (ORCA's piecewise)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
from jax import Array

from sgjax.environment.options import HumanOptions
from sgjax.evaluation.forecasting import OBSERVE, scored
from sgjax.humans.forces import (
    SocialForceParams,
    cap_speed,
    desired_force,
    helbing_interaction,
    moussaid_interaction,
    unit,
)
from sgjax.humans.hsfm import HsfmParams, headed_step, pair_force
from sgjax.humans.orca_model import OrcaParams
from sgjax.humans.tracks import TrackWindows
from sgjax.kernels.orca import nearest_bodies, orca_velocity

SUBSTEPS = 4  # explicit steps per recorded row (0.1 s at ETH/UCY's 0.4 s)
MAX_SPEED_FACTOR = 1.3  # a pedestrian never walks faster than this times its own speed
# m/s: a pedestrian whose mean observed velocity is slower than this is standing (it wants to
# stay: desired speed 0). Its goal would lie on itself, where the direction to it turns with
# every millimetre and the loss's gradient in the constants reaches 1e7 (two waiting people in
# HOTEL did that).
STANDING = 0.1


# the models a forecast walks, each with the constants it takes
MODELS = ("moussaid", "helbing", "hsfm", "orca")
ModelParams = SocialForceParams | HsfmParams | OrcaParams
HSFM_SUBSTEPS = 20  # explicit steps per row for the headed model (0.02 s: its stable step)
RADIUS = HumanOptions().human_radius  # m: the headed and ORCA pedestrians' radius
WINDOW_BATCH = 64  # windows walked together (the rest in a loop): bounds the memory
ORCA_WINDOW_BATCH = 16  # the same for ORCA (UNIV under grad: 1.2 GB; 2 took 1.45x as long)
HSFM_WINDOW_BATCH = 8  # and for the headed model (20 sub-steps a row)
ORCA_NEIGHBORS = 10  # the nearest others an ORCA pedestrian avoids (CrowdNav's max_neighbors)
# the state a forecast carries per pedestrian [P]: x, y, vx, vy, heading, turn rate
Walkers = tuple[Array, Array, Array, Array, Array, Array]


def default_constants(model: str) -> ModelParams:
    """The constants ``model`` takes when none are given (sgjax's defaults)."""
    _check_model(model)
    return {"hsfm": HsfmParams, "orca": OrcaParams}.get(model, SocialForceParams)()


def substeps_of(model: str) -> int:
    """Explicit steps per recorded row for ``model``."""
    return HSFM_SUBSTEPS if model == "hsfm" else SUBSTEPS


def _walk(p: ModelParams, state: Walkers, intent: tuple[Array, Array, Array, Array],
          mask: Array, h: float, model: str = "moussaid") -> Walkers:
    """One explicit step of ``h`` s of pedestrians ``[P]`` (``mask``: the real ones) with
    their ``intent`` (:func:`intentions`)."""
    x, y, vx, vy, heading, omega = state
    goal_x, goal_y, speed, top = intent
    pair = (mask[:, None] & mask[None, :] & ~jnp.eye(mask.shape[0], dtype=bool))
    weight = pair.astype(jnp.float32)
    if model == "orca":
        vx, vy = _orca_velocity(p, x, y, vx, vy, goal_x, goal_y, speed, top, pair, h)
    elif model == "hsfm":
        vx, vy, heading, omega = _headed(p, state, goal_x, goal_y, speed, weight, h)
        vx, vy = cap_speed(vx, vy, top)
    else:
        fx, fy = desired_force(x, y, vx, vy, goal_x, goal_y, speed, p.tau)
        if model == "helbing":
            ex, ey, _ = unit(goal_x - x, goal_y - y)
            sx, sy = helbing_interaction(x, y, ex, ey, x, y, vx, vy, weight, p)
        else:
            sx, sy = moussaid_interaction(x, y, vx, vy, x, y, vx, vy, weight, p)
        vx, vy = cap_speed(vx + h * (fx + sx), vy + h * (fy + sy), top)
    return x + h * vx, y + h * vy, vx, vy, heading, omega


def _headed(p: HsfmParams, state: Walkers, goal_x: Array, goal_y: Array, speed: Array,
            weight: Array, h: float) -> tuple[Array, Array, Array, Array]:
    """The headed model's step among the window's pedestrians (``weight [P, P]``)."""
    x, y, vx, vy, heading, omega = state
    ex, ey, far = unit(goal_x - x, goal_y - y)
    f0x, f0y = p.mass * (speed * ex - vx) / p.tau, p.mass * (speed * ey - vy) / p.tau
    # standing on its goal (or padding): it faces where it faces (the direction to the goal
    # is undefined, and atan2's gradient at the origin is not finite)
    ex, ey = jnp.where(far > 1e-6, ex, jnp.cos(heading)), jnp.where(far > 1e-6, ey,
                                                                    jnp.sin(heading))
    fx, fy = pair_force(x[:, None] - x[None, :], y[:, None] - y[None, :],
                        jnp.full(weight.shape, 2.0 * RADIUS), vx[None, :] - vx[:, None],
                        vy[None, :] - vy[:, None], p)
    fex, fey = jnp.sum(weight * fx, axis=1), jnp.sum(weight * fy, axis=1)
    inertia = 0.5 * p.mass * RADIUS * RADIUS
    return headed_step(p, vx, vy, heading, omega, f0x, f0y, fex, fey, ex, ey, inertia, h)


def _orca_velocity(p: OrcaParams, x: Array, y: Array, vx: Array, vy: Array, goal_x: Array,
                   goal_y: Array, speed: Array, top: Array, pair: Array, h: float
                   ) -> tuple[Array, Array]:
    """Each pedestrian's ORCA velocity among its nearest others of the window (``pair``)."""
    ex, ey, distance = unit(goal_x - x, goal_y - y)
    pref = jnp.minimum(speed, distance / h)  # m/s: slowing within a step of the goal
    near, valid = nearest_bodies(x, y, x, y, pair, ORCA_NEIGHBORS)
    count = near.shape[1]

    def one(i: Array) -> tuple[Array, Array]:
        k = near[i]
        return orca_velocity(x[i], y[i], vx[i], vy[i], RADIUS, ex[i] * pref[i],
                             ey[i] * pref[i], top[i], x[k], y[k], vx[k], vy[k],
                             jnp.full(count, RADIUS), jnp.full(count, 0.5), valid[i],
                             p.time_horizon, h)

    return jax.vmap(one)(jnp.arange(x.shape[0]))


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


def _start(x: Array, y: Array, k: Array | int, dt: float) -> Walkers:
    """The walkers at recorded row ``k`` of one window (``x, y [T, P]``): its positions, the
    step that led there as velocity, facing along it, not turning."""
    vx, vy = (x[k] - x[k - 1]) / dt, (y[k] - y[k - 1]) / dt
    return x[k], y[k], vx, vy, jnp.arctan2(vy, vx), jnp.zeros_like(vx)


def _rows(p: ModelParams, start: Walkers, intent: tuple[Array, Array, Array, Array],
          mask: Array, rows: int, dt: float, substeps: int, model: str = "moussaid"
          ) -> tuple[Array, Array]:
    """``(x, y) [rows, P]``: one window's pedestrians walked from ``start``."""
    h = dt / substeps
    # ORCA's programs (nested loops over its lines) and the headed model's many sub-steps keep
    # too much for the gradient: recompute each step's on the way back instead of storing it
    walk = (jax.checkpoint(_walk, static_argnums=(4, 5)) if model in ("orca", "hsfm")
            else _walk)

    def substep(_: int, state: Walkers) -> Walkers:
        return walk(p, state, intent, mask, h, model)

    def row(state: Walkers, _: None) -> tuple[Walkers, tuple[Array, Array]]:
        if substeps <= SUBSTEPS:  # a few: unrolled, as XLA fuses them best
            for _ in range(substeps):
                state = walk(p, state, intent, mask, h, model)
        else:  # many (the headed model's): a loop, or the program grows with them
            state = jax.lax.fori_loop(0, substeps, substep, state)
        return state, (state[0], state[1])

    return jax.lax.scan(row, start, None, length=rows)[1]


def social_force_forecast(p: ModelParams, windows: TrackWindows, dt: float,
                          observe: int = OBSERVE, substeps: int | None = None,
                          model: str = "moussaid") -> tuple[Array, Array]:
    """``(x, y) [N, P, Pw]`` (m): every window's scored pedestrians walked by ``model``
    (:data:`MODELS`) from the last observed row over the ``P`` forecast rows (module doc);
    ``substeps`` per row (default :func:`substeps_of`)."""
    _check_model(model)
    substeps = substeps_of(model) if substeps is None else substeps
    rows = windows.x.shape[1] - observe
    intent = intentions(windows, dt, observe)
    mask = scored(windows)

    def one(x: Array, y: Array, intent: tuple[Array, ...], m: Array) -> tuple[Array, Array]:
        return _rows(p, _start(x, y, observe - 1, dt), intent, m, rows, dt, substeps, model)

    return _by_windows(model, one, windows.x, windows.y, intent, mask)


def _by_windows(model: str, fn: Callable[..., Any], *per_window: Any) -> Any:
    """``fn`` of every window (each argument's leading axis), a batch of windows at a time
    (:data:`WINDOW_BATCH`; ORCA's :data:`ORCA_WINDOW_BATCH`, the headed model's
    :data:`HSFM_WINDOW_BATCH`): ``vmap`` within a batch, a loop over batches, so the memory
    grows with a batch, not with a scene (UNIV's windows hold 57 people; ORCA's nested
    programs under ``grad`` keep a value per line pair and person)."""
    batch = {"orca": ORCA_WINDOW_BATCH, "hsfm": HSFM_WINDOW_BATCH}.get(model, WINDOW_BATCH)
    return jax.lax.map(lambda args: fn(*args), per_window, batch_size=batch)


def rollout_loss(p: ModelParams, windows: TrackWindows, dt: float, rows: int = 1,
                 observe: int = OBSERVE, substeps: int | None = None,
                 model: str = "moussaid") -> Array:
    """Mean squared error (m^2) of ``rows`` rows walked by ``model`` from each recorded row of
    the forecast part (teacher forcing at the start: position and velocity from the
    recording, the intentions of :func:`intentions`) against the recorded rows that follow,
    over every scored pedestrian and walked row (``rows`` 1: the one-row loss; a few rows: the
    short-rollout loss, where the model's own errors compound as in a forecast). Starts whose
    rows would run past the window are left out."""
    _check_model(model)
    substeps = substeps_of(model) if substeps is None else substeps
    intent = intentions(windows, dt, observe)
    mask = scored(windows)
    last = windows.x.shape[1] - rows
    if last < observe:
        raise ValueError(f"rows {rows}: a window of {windows.x.shape[1]} rows observed for "
                         f"{observe} has no start {rows} rows before its end")

    def one(x: Array, y: Array, intent: tuple[Array, ...], m: Array) -> Array:
        def at(k: Array) -> Array:
            px, py = _rows(p, _start(x, y, k, dt), intent, m, rows, dt, substeps, model)
            later = k + 1 + jnp.arange(rows)
            error = jnp.square(px - x[later]) + jnp.square(py - y[later])  # [rows, P]
            return jnp.sum(jnp.where(m[None, :], error, 0.0))

        return jnp.sum(jax.vmap(at)(jnp.arange(observe - 1, last)))

    total = jnp.sum(_by_windows(model, one, windows.x, windows.y, intent, mask))
    return total / jnp.maximum(jnp.sum(mask) * (last - observe + 1) * rows, 1)


def one_row_loss(p: ModelParams, windows: TrackWindows, dt: float, observe: int = OBSERVE,
                 substeps: int | None = None, model: str = "moussaid") -> Array:
    """:func:`rollout_loss` of one row: the teacher-forced one-step loss."""
    return rollout_loss(p, windows, dt, 1, observe, substeps, model)


def _check_model(model: str) -> None:
    if model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
