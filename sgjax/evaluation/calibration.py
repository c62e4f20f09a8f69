"""A pedestrian model's constants (the Moussaid law, Helbing and Molnar's potentials, the
headed social force model, ORCA) fitted to recorded pedestrians by gradient (issue 68): Adam
(optax) on the logarithms of the constants (so they stay positive) over the teacher-forced loss
of :func:`sgjax.evaluation.force_forecast.rollout_loss` (one row, or a short rollout of a few
rows), averaged over the recordings given (the leave-one-scene-out protocol fits on four scenes
and forecasts the fifth)."""

from __future__ import annotations

import time
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import optax
from jax import Array

from sgjax.evaluation.force_forecast import ModelParams, default_constants, rollout_loss
from sgjax.humans.forces import SocialForceParams
from sgjax.humans.tracks import TrackWindows

# The interaction and relaxation constants a fit moves, per law (the wall constants play no
# part in an open recording; Helbing's field-of-view weight is a share, not fitted)
FITTED = ("tau", "social_strength", "lambda_importance", "gamma", "n", "n_prime")
# (the headed model's contact stiffness and friction act only in contact, which recorded people
# avoid; ORCA's one continuous constant among people is its time horizon)
FITTED_BY_MODEL = {"moussaid": FITTED, "helbing": ("tau", "v0", "sigma", "ellipse_dt"),
                   "hsfm": ("tau", "strength", "falloff", "k_orthogonal", "k_damping",
                            "k_lambda"),
                   "orca": ("time_horizon",)}
# TrajNet++'s hand-tuned social-force constants (trajnetplusplusbaselines,
# classical/socialforce.py: Kreiss's socialforce, Helbing and Molnar's potentials with tau
# 0.5 s, V0 2.1 m^2/s^2, sigma 0.3 m, and the ellipse's step its simulation step of 1/20 s)
TRAJNET_CONSTANTS: dict[str, ModelParams] = {
    "helbing": SocialForceParams(tau=0.5, v0=2.1, sigma=0.3, ellipse_dt=0.05),
}


def fit_social_force(windows: Sequence[TrackWindows], dt: float, steps: int = 100,
                     learning_rate: float = 0.05, start: ModelParams | None = None,
                     names: Sequence[str] | None = None, model: str = "moussaid",
                     max_seconds: float | None = None, rows: int = 1
                     ) -> tuple[ModelParams, list[float]]:
    """``(fitted constants, the loss before each step)``: ``steps`` Adam steps (gradient
    clipped to norm 1) on the log of the constants ``names`` (default
    ``FITTED_BY_MODEL[model]``), from ``start`` (default the model's defaults), minimising the
    mean of each recording's loss over ``rows`` walked rows (m^2; ``dt`` s per row; 1: the
    one-row loss) under ``model``; ``max_seconds`` stops earlier once that much time has
    passed (the compile included)."""
    if model not in FITTED_BY_MODEL:
        raise ValueError(f"model must be one of {tuple(FITTED_BY_MODEL)}, got {model!r}")
    names = FITTED_BY_MODEL[model] if names is None else tuple(names)
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps}")
    if not windows:
        raise ValueError("fit_social_force needs at least one recording's windows")
    start = start or default_constants(model)
    unknown = [n for n in names if not hasattr(start, n)]
    if unknown:
        raise ValueError(f"no {type(start).__name__} constant {unknown[0]!r}; fit among "
                         f"{FITTED_BY_MODEL[model]}")
    theta = {n: jnp.log(jnp.float32(getattr(start, n))) for n in names}

    def constants(theta: dict[str, Array]) -> ModelParams:
        return start.replace(**{n: jnp.exp(v) for n, v in theta.items()})

    def loss(theta: dict[str, Array]) -> Array:
        return sum(rollout_loss(constants(theta), w, dt, rows, model=model)
                   for w in windows) / len(windows)

    optimiser = optax.chain(optax.clip_by_global_norm(1.0), optax.adam(learning_rate))

    @jax.jit
    def step(theta: dict, state: optax.OptState) -> tuple[dict, optax.OptState, Array]:
        value, grads = jax.value_and_grad(loss)(theta)
        updates, state = optimiser.update(grads, state)
        return optax.apply_updates(theta, updates), state, value

    state = optimiser.init(theta)
    history = []
    began = time.perf_counter()
    for _ in range(steps):
        theta, state, value = step(theta, state)
        history.append(float(value))
        if max_seconds is not None and time.perf_counter() - began > max_seconds:
            break
    return constants(theta), history
