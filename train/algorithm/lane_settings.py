"""Algorithm settings that the lanes of one training call may set differently.

``train.sweep`` trains trials that differ only in these numbers (and in reward-term weights and
observation masks) side by side: each lane holds its values in its runner state
(``RunnerState.hyper``), and the compiled program reads them there for the settings it was told
vary (``varied``). Every other setting, and these where they do not vary, is a constant of the
program, so a run that varies nothing compiles and rounds as it did before lane settings existed.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from sgjax.terms.base import ConfigError
from train.algorithm.config import AlgorithmConfig

LANE_SETTINGS = ("learning_rate", "ent_coef", "vf_coef", "clip_eps", "gamma", "gae_lambda",
                 "team_reward")


class LaneSettings:
    """The :data:`LANE_SETTINGS` of one trainer: which of them vary across lanes, and how the
    program reads each (:meth:`read`)."""

    def __init__(self, algorithm: AlgorithmConfig, varied: Iterable[str] = ()):
        varied = frozenset(varied)
        unknown = sorted(varied - set(LANE_SETTINGS))
        if unknown:
            raise ConfigError(f"Trainer(varied=...): {unknown} are not lane settings "
                              f"{list(LANE_SETTINGS)}")
        self.algorithm = algorithm
        self.varied = varied

    def read(self, hyper: dict | None, name: str) -> Any:
        """A lane setting (:data:`LANE_SETTINGS`, or ``gamma_lambda``) as the program reads it:
        the lane's number from ``hyper`` where lanes vary it, else the config's value as a
        Python constant."""
        a = self.algorithm
        lane = (self.varied & {"gamma", "gae_lambda"} if name == "gamma_lambda"
                else name in self.varied)
        if hyper is not None and lane:
            return hyper[name]
        return a.gamma * a.gae_lambda if name == "gamma_lambda" else getattr(a, name)

    def defaults(self) -> dict[str, Array]:
        """The configured values, float32, and ``gamma_lambda``, GAE's ``gamma x gae_lambda``
        rounded to float32 once from the float64 product."""
        a = self.algorithm
        hyper = {name: jnp.float32(getattr(a, name)) for name in LANE_SETTINGS}
        hyper["gamma_lambda"] = jnp.float32(a.gamma * a.gae_lambda)
        return hyper

    def with_values(self, hyper: dict | None) -> dict[str, Array]:
        """:meth:`defaults` with ``hyper`` ({name: value}) on top, ``gamma_lambda`` recomputed
        where ``gamma`` or ``gae_lambda`` is given without it (``Trainer.init``). A concrete
        value that differs from the config for a setting that does not vary is the error
        :meth:`lane` gives (the program would read the config's); traced values (``init``
        under ``vmap``) come from :meth:`lane`, which checked them."""
        settings = self.defaults()
        for name, value in (hyper or {}).items():
            if name not in settings:
                raise ConfigError(f"hyper: {name!r} is not a lane setting; lanes may differ "
                                  f"in {list(LANE_SETTINGS)}")
            settings[name] = jnp.asarray(value, jnp.float32)
            if (name in LANE_SETTINGS and not isinstance(value, jax.core.Tracer)
                    and name not in self.varied
                    and np.any(np.asarray(value, np.float32) != settings[name].dtype.type(
                        getattr(self.algorithm, name)))):
                self.lane({name: float(np.asarray(value).ravel()[0])})  # names the setting
        if {"gamma", "gae_lambda"} & set(hyper or {}) and "gamma_lambda" not in hyper:
            settings["gamma_lambda"] = settings["gamma"] * settings["gae_lambda"]
        return settings

    def lane(self, values: dict[str, float]) -> dict[str, np.ndarray]:
        """A lane's ``hyper`` (float32 numpy): the configured settings with ``values`` on top,
        and their ``gamma_lambda`` rounded once from the float64 product, as :meth:`defaults`
        does (a lane with the configured values trains exactly as the config alone). A value
        that differs from the config for a setting that does not vary is an error."""
        a = self.algorithm
        merged = {name: float(getattr(a, name)) for name in LANE_SETTINGS}
        for name, value in values.items():
            if name not in merged:
                raise ConfigError(f"hyper: {name!r} is not a lane setting; lanes may differ "
                                  f"in {list(LANE_SETTINGS)}")
            if name not in self.varied and float(value) != merged[name]:
                raise ConfigError(f"hyper: {name} = {value} differs from the config's "
                                  f"{merged[name]}, but this Trainer reads {name} from the "
                                  f"config: build it with Trainer(config, varied=[{name!r}])")
            merged[name] = float(value)
        out = {name: np.float32(value) for name, value in merged.items()}
        out["gamma_lambda"] = np.float32(merged["gamma"] * merged["gae_lambda"])
        return out

    def loss_coefficients(self, hyper: dict | None) -> tuple[Any, Any, Any]:
        """``(clip_eps, vf_coef, ent_coef)`` as the program reads them."""
        return (self.read(hyper, "clip_eps"), self.read(hyper, "vf_coef"),
                self.read(hyper, "ent_coef"))
