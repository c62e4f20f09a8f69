"""Observation terms and the Observer (``sgjax.observations.OBSERVATIONS`` lists them by name)."""

from sgjax.observations import conflict_zones, lidar, others, own  # noqa: F401  (registers the terms)
from sgjax.observations.base import OBSERVATIONS, ObservationTerm, Observer
from sgjax.observations.columns import Columns, ObservationColumns
from sgjax.observations.lidar import Lidar
from sgjax.observations.others import FEATURES, Others
from sgjax.observations.own import (
    CollisionFlag,
    Goal,
    GoalDistance,
    Pose,
    PreferredSpeed,
    SuccessFlag,
    TimeLeft,
    Velocity,
    Waypoint,
)

__all__ = [
    "FEATURES",
    "OBSERVATIONS",
    "CollisionFlag",
    "Columns",
    "Goal",
    "GoalDistance",
    "Lidar",
    "ObservationColumns",
    "ObservationTerm",
    "Observer",
    "Others",
    "Pose",
    "PreferredSpeed",
    "SuccessFlag",
    "TimeLeft",
    "Velocity",
    "Waypoint",
]
