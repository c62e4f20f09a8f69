"""sgjax: a JAX-native, batched, differentiable multi-robot social-navigation simulator."""

from sgjax import maps
from sgjax.dynamics import PRESETS, RobotPreset
from sgjax.env import EnvParams, EnvState, SocialNavEnv
from sgjax.registry import make, registered

__all__ = [
    "PRESETS",
    "EnvParams",
    "EnvState",
    "RobotPreset",
    "SocialNavEnv",
    "make",
    "maps",
    "registered",
]
__version__ = "0.1.0"
