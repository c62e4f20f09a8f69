"""sgjax: a JAX-native, batched, differentiable multi-robot social-navigation simulator."""

from sgjax import maps
from sgjax.dynamics import PRESETS, RobotPreset
from sgjax.environment.env import SocialNavEnv
from sgjax.environment.registry import make, registered
from sgjax.types import EnvParams, EnvState
from sgjax.version import __version__

__all__ = [
    "PRESETS",
    "EnvParams",
    "EnvState",
    "RobotPreset",
    "SocialNavEnv",
    "__version__",
    "make",
    "maps",
    "registered",
]
