"""What every metric shares: its catalogue entry (:class:`MetricInfo`) and the base class of a
metric family (:class:`Metric`); the thresholds are in
:mod:`sgjax.evaluation.metrics.constants`.

A metric family is a small class: the metrics it gives (one or more :class:`MetricInfo`), an
accumulator (any pytree, ``[R]`` per robot or scalars) started empty, updated once per step
from the step's shared quantities (:class:`~sgjax.evaluation.metrics.step_view.StepView`) and
finalised into values from the episode's end
(:class:`~sgjax.evaluation.metrics.step_view.EpisodeEnd`). Registered with
:func:`sgjax.evaluation.metrics.register_metric`, its metrics appear in every evaluation.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any, ClassVar

import jax.numpy as jnp
import numpy as np
from jax import Array

from sgjax.evaluation.metrics.constants import MetricConstants

if TYPE_CHECKING:
    from sgjax.evaluation.metrics.step_view import EpisodeEnd, StepView

LEVELS = ("robot", "episode")
REDUCTIONS = ("mean", "sum")


@dataclasses.dataclass(frozen=True)
class MetricInfo:
    """One metric's catalogue entry. ``level`` says whether it is measured per robot (values
    ``[R]``, NaN for robots not in the episode; reduced over an episode's robots by ``reduce``,
    ``"mean"`` or ``"sum"``) or per episode (a scalar); ``binary`` metrics (yes/no per episode)
    get a Wilson interval, the others a Student-t interval over episodes. ``unit`` is an SI
    unit or ``fraction``, ``count``, ``ratio``, ``steps``; ``source`` names where the
    definition comes from."""

    name: str
    unit: str
    level: str
    reduce: str = "mean"
    binary: bool = False
    definition: str = ""
    source: str = ""

    def check(self) -> None:
        """Raise ``ValueError`` naming the metric and the field that is wrong."""
        if not self.name.isidentifier():
            raise ValueError(f"metric name {self.name!r} must be a Python identifier")
        if self.level not in LEVELS:
            raise ValueError(f"metric {self.name!r}: level must be one of {LEVELS}, "
                             f"got {self.level!r}")
        if self.reduce not in REDUCTIONS:
            raise ValueError(f"metric {self.name!r}: reduce must be one of {REDUCTIONS}, "
                             f"got {self.reduce!r}")
        for field in ("unit", "definition", "source"):
            if not getattr(self, field).strip():
                raise ValueError(f"metric {self.name!r}: {field} must not be empty")


def robot_metric(name: str, unit: str, definition: str, source: str, reduce: str = "mean"
                 ) -> MetricInfo:
    """A per-robot metric (values ``[R]``), reduced over an episode's robots by ``reduce``."""
    return MetricInfo(name, unit, "robot", reduce, False, definition, source)


def episode_metric(name: str, unit: str, definition: str, source: str, binary: bool = False
                   ) -> MetricInfo:
    """A per-episode metric (a scalar per episode); ``binary``: yes/no."""
    return MetricInfo(name, unit, "episode", "mean", binary, definition, source)


class Metric:
    """Base class of a metric family: the metrics in ``infos`` share one accumulator.

    Subclasses set ``infos`` and override :meth:`start`, :meth:`update` and :meth:`finalize`.
    Everything runs inside the jitted step of one environment (batched with ``vmap`` from
    outside): no Python branching on traced values. ``per_step = False`` marks metrics that
    are not computed from the step (the counterfactual ones, filled in from extra lanes by
    :mod:`sgjax.evaluation.counterfactual`): they read NaN unless those lanes run."""

    infos: ClassVar[tuple[MetricInfo, ...]] = ()
    per_step: ClassVar[bool] = True

    @property
    def key(self) -> str:
        """The family's name in the registry and in ``MetricState.tallies``."""
        return type(self).__name__

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(info.name for info in self.infos)

    def start(self, num_robots: int, num_zones: int, constants: MetricConstants) -> Any:
        """The empty accumulator of an episode with ``num_robots`` robot slots and
        ``num_zones`` tracked conflict zones (0 without zone books)."""
        return ()

    def update(self, tally: Any, view: StepView) -> Any:
        """Fold one step into the accumulator (``view.running`` is False once the episode has
        ended: nothing may change then)."""
        return tally

    def finalize(self, tally: Any, end: EpisodeEnd) -> dict[str, Array]:
        """``{name: value}`` for every metric in ``infos``: ``[R]`` for robot-level ones (the
        caller sets robots not in the episode to NaN), a scalar for episode-level ones; NaN
        where a metric is undefined."""
        raise NotImplementedError(f"{self.key}.finalize")


NAN = np.float32(np.nan)  # a numpy scalar: importing starts no XLA backend


def known(value: Array, ok: Array) -> Array:
    """``value`` where ``ok``, NaN elsewhere (an undefined metric)."""
    return jnp.where(ok, value, NAN)


def team_success(present: Array, succeeded: Array) -> Array:
    """Team success from ``present`` and ``succeeded`` ``[..., R]``: every robot in the episode
    arrived, and there was one. ``[...]`` bool."""
    return jnp.all(succeeded | ~present, axis=-1) & jnp.any(present, axis=-1)
