"""Social-navigation metrics, accumulated inside the jitted step (no host-side trajectories).

Metrics are registered classes (:func:`register_metric`, Waymax's model): each family
(:class:`Metric`) declares its metrics (:class:`MetricInfo`: name, unit, level, reduction,
definition, source) and keeps a small accumulator, updated once per step from a shared view of
the step and finalised at the episode's end. :data:`METRICS` is the catalogue of every
registered metric; :func:`start`, :func:`update`, :func:`finalize`, :func:`per_episode` and
:func:`episode_done` run them all. The families, one module each:

* ``outcome``: success, team success, clean success, timeouts, collision ends, episode length,
  stuck ends;
* ``collisions``: collision onsets by kind;
* ``paths``: time to goal, path length, SPL, path irregularity;
* ``stops``: stop time, freezes, deadlock;
* ``smoothness``: velocity and turn-rate changes, acceleration, jerk;
* ``proximity``: closest approach, personal spaces;
* ``ttc``: time to collision;
* ``mini_game``: order violations at conflict zones, makespan, flow rate;
* ``recorded``: log deviation and people reached, among recorded people;
* and the counterfactual metrics (``counterfactuals``), filled in by the lanes of
  :mod:`sgjax.evaluation.counterfactual`.

The framework: ``base`` (:class:`Metric`, :class:`MetricInfo`), ``constants``
(:class:`MetricConstants`), ``registration`` (:func:`register_metric`, :data:`METRICS`),
``step_view`` (:class:`StepView`, :class:`EpisodeEnd`), ``accumulate`` (:class:`MetricState`
and the composed functions). Every definition, constant and source is in docs/metrics.md,
whose tables are generated from the registry (``python -m sgjax.evaluation.metrics.catalogue``,
module ``catalogue``).
"""

# The import order is the catalogue's order: each module registers its metrics.
# isort: off
from sgjax.evaluation.metrics import outcome, collisions, paths, stops  # noqa: F401
from sgjax.evaluation.metrics import smoothness, proximity, ttc, mini_game  # noqa: F401
from sgjax.evaluation.metrics import actions  # noqa: F401
from sgjax.evaluation.metrics import counterfactuals  # noqa: F401
from sgjax.evaluation.metrics import recorded  # noqa: F401
# isort: on
from sgjax.evaluation.metrics.accumulate import (
    MetricState,
    episode_done,
    finalize,
    per_episode,
    start,
    update,
)
from sgjax.evaluation.metrics.base import (
    Metric,
    MetricInfo,
    episode_metric,
    known,
    robot_metric,
    team_success,
)
from sgjax.evaluation.metrics.constants import DEFAULT_CONSTANTS, SPACE_NAMES, MetricConstants
from sgjax.evaluation.metrics.registration import (
    METRICS,
    MetricRegistry,
    register_metric,
    unregister_metric,
)
from sgjax.evaluation.metrics.step_view import EpisodeEnd, StepView
from sgjax.evaluation.metrics.ttc import time_to_collision

__all__ = [
    "DEFAULT_CONSTANTS",
    "METRICS",
    "SPACE_NAMES",
    "EpisodeEnd",
    "Metric",
    "MetricConstants",
    "MetricInfo",
    "MetricRegistry",
    "MetricState",
    "StepView",
    "episode_done",
    "episode_metric",
    "finalize",
    "known",
    "per_episode",
    "register_metric",
    "robot_metric",
    "start",
    "team_success",
    "time_to_collision",
    "unregister_metric",
    "update",
]
