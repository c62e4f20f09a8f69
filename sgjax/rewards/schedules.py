"""Reward-weight schedules: constant, linear ramps and piecewise curves over environment steps.

A schedule is a pytree of breakpoints ``(steps [K], values [K])``, so it lives in params: a sweep
can ``vmap`` over weights without recompiling. Time is counted in steps of one environment since
its first reset (``state.total_steps``, kept across auto-resets); with ``N`` environments in a
batch, ``N`` times as many transitions have been collected. SocialGym 2.0's
``LinearWeightScheduler`` was neither linear nor counted in steps (it moved on each reset,
hyperbolically); this one is what its name says.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.terms.base import ConfigError

INTERPOLATIONS = ("linear", "step")


@struct.dataclass
class Schedule:
    """A weight as a function of environment steps: between breakpoints ``linear``-ly
    interpolated or held (``step``: the value of the last breakpoint passed); constant before
    the first and after the last breakpoint."""

    steps: Array  # [K] float32, increasing
    values: Array  # [K] float32
    interpolation: str = struct.field(pytree_node=False, default="linear")

    def __call__(self, t: Array) -> Array:
        t = jnp.asarray(t, jnp.float32)
        if self.values.shape[0] == 1:  # a constant: what either rule gives, without the search
            return jnp.broadcast_to(self.values[0], t.shape)
        if self.interpolation == "linear":
            return jnp.interp(t, self.steps, self.values)
        passed = jnp.sum(self.steps <= t) - 1
        return self.values[jnp.clip(passed, 0, self.values.shape[0] - 1)]


def constant(value: float) -> Schedule:
    return Schedule(jnp.zeros(1, jnp.float32), jnp.full(1, value, jnp.float32))


def linear(start: float, end: float, steps: float, begin: float = 0.0) -> Schedule:
    """From ``start`` at step ``begin`` to ``end`` at ``begin + steps``."""
    return Schedule(jnp.asarray([begin, begin + steps], jnp.float32),
                    jnp.asarray([start, end], jnp.float32))


def piecewise(points: Sequence[Sequence[float]], interpolation: str = "linear") -> Schedule:
    """Through ``[[step, value], ...]`` (steps increasing)."""
    steps = [float(p[0]) for p in points]
    values = [float(p[1]) for p in points]
    return Schedule(jnp.asarray(steps, jnp.float32), jnp.asarray(values, jnp.float32),
                    interpolation)


def _number(where: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"{where}: expected a number, got {value!r}")
    return float(value)


def parse_schedule(where: str, spec: Any) -> Schedule:
    """A number (constant), or a mapping: ``{schedule: constant, value}``,
    ``{schedule: linear, start, end, steps, begin=0}`` or
    ``{schedule: piecewise, points: [[step, value], ...], interpolation: linear|step}``."""
    if isinstance(spec, Schedule):
        return spec
    if not isinstance(spec, Mapping):
        return constant(_number(where, spec))
    kinds = {"constant": ("value",), "linear": ("start", "end", "steps", "begin"),
             "piecewise": ("points", "interpolation")}
    kind = spec.get("schedule")
    if kind not in kinds:
        raise ConfigError(f"{where}.schedule: expected one of {list(kinds)}, got {kind!r}")
    extra = sorted(set(spec) - {"schedule", *kinds[kind]})
    if extra:
        raise ConfigError(f"{where}: unknown key(s) {extra} for a {kind} schedule; valid keys: "
                          f"{', '.join(kinds[kind])}")

    def need(key: str) -> Any:
        if key not in spec:
            raise ConfigError(f"{where}: a {kind} schedule needs {key!r}")
        return spec[key]

    if kind == "constant":
        return constant(_number(f"{where}.value", need("value")))
    if kind == "linear":
        steps = _number(f"{where}.steps", need("steps"))
        if steps <= 0:
            raise ConfigError(f"{where}.steps: must be positive, got {steps}")
        return linear(_number(f"{where}.start", need("start")),
                      _number(f"{where}.end", need("end")), steps,
                      _number(f"{where}.begin", spec.get("begin", 0.0)))
    points = need("points")
    if not isinstance(points, Sequence) or not points or not all(
            isinstance(p, Sequence) and len(p) == 2 for p in points):
        raise ConfigError(f"{where}.points: expected [[step, value], ...], got {points!r}")
    steps = [_number(f"{where}.points[{i}][0]", p[0]) for i, p in enumerate(points)]
    for i in range(1, len(steps)):
        if steps[i] <= steps[i - 1]:
            raise ConfigError(f"{where}.points: steps must increase, got {steps}")
    values = [_number(f"{where}.points[{i}][1]", p[1]) for i, p in enumerate(points)]
    interpolation = spec.get("interpolation", "linear")
    if interpolation not in INTERPOLATIONS:
        raise ConfigError(f"{where}.interpolation: expected one of {INTERPOLATIONS}, "
                          f"got {interpolation!r}")
    return piecewise(list(zip(steps, values, strict=True)), interpolation)
