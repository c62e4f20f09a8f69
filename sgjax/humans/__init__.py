"""Pedestrians driven by social forces (see :mod:`sgjax.humans.crowd`)."""

from sgjax.humans.crowd import (
    FORCE_MODELS,
    GOAL_MODES,
    WALL_MODELS,
    HumanConfig,
    HumanParams,
    HumanState,
)
from sgjax.humans.forces import SocialForceParams

__all__ = [
    "FORCE_MODELS",
    "GOAL_MODES",
    "WALL_MODELS",
    "HumanConfig",
    "HumanParams",
    "HumanState",
    "SocialForceParams",
]
