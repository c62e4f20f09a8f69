"""Reward terms, weight schedules and the Rewarder (``sgjax.rewards.REWARDS`` lists terms)."""

from sgjax.rewards import navigation, social, zone_order  # noqa: F401  (registers the terms)
from sgjax.rewards.base import REWARDS, Rewarder, RewardParams, RewardTerm
from sgjax.rewards.schedules import Schedule, constant, linear, parse_schedule, piecewise

__all__ = [
    "REWARDS",
    "RewardParams",
    "RewardTerm",
    "Rewarder",
    "Schedule",
    "constant",
    "linear",
    "parse_schedule",
    "piecewise",
]
