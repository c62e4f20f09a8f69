"""Pedestrians driven by social forces (see :mod:`sgjax.humans.pedestrians`)."""

from sgjax.humans.forces import SocialForceParams
from sgjax.humans.pedestrians import (
    FORCE_MODELS,
    GOAL_MODES,
    WALL_MODELS,
    HumanConfig,
    HumanParams,
    HumanState,
)

__all__ = [
    "FORCE_MODELS",
    "GOAL_MODES",
    "WALL_MODELS",
    "HumanConfig",
    "HumanParams",
    "HumanState",
    "SocialForceParams",
]
