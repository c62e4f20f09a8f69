"""Training configuration: YAML files validated into frozen dataclasses.

A config file has the sections ``env``, ``algorithm``, ``network``, ``evaluation`` and
``logging`` plus ``seed`` and ``num_seeds`` (see ``train/configs/doorway.yaml``, and
``docs/training.md`` for every key and the SocialGym 2.0 key it replaces). Unknown keys and bad
values are errors naming the file, the key and the nearest valid key. ``--set a.b=value`` on the
command line overrides one key (the value is read as YAML).
"""

from __future__ import annotations

import dataclasses
import re
import types
import typing
from collections.abc import Mapping
from functools import partial
from pathlib import Path
from typing import Any

import yaml

from sgjax.environment.options import KEYWORDS, MakeOptions
from sgjax.terms.base import ConfigError, suggest

TRAINER_OBSERVATIONS = "navigation"  # the trainer's default observation preset


@dataclasses.dataclass(frozen=True)
class EnvSection:
    """What to train on: the scenarios, the robot-count curriculum, and any option of
    ``sgjax.make`` (``sgjax.environment.options``: ``action_mode``, ``robots``, ``observations``,
    ``rewards``, ``num_humans``, ``dt``, ``num_arcs``, ...) as a key of the same name, validated
    by the same code. ``curriculum`` is ``[[env_step, num_agents], ...]``: from each total
    environment step on, episodes have that many robots (SocialGym's ``agents_settings``), so
    ``num_agents`` itself is not a key; ``max_agents`` defaults to the curriculum's largest
    count. ``preset`` sets the observation and reward presets at once (cadrl,
    enforced_order); observations default to ``navigation``."""

    scenarios: tuple[str, ...] = ("doorway",)
    curriculum: tuple[tuple[int, int], ...] = ((0, 4),)
    preset: str | None = None
    make: MakeOptions = dataclasses.field(
        default_factory=lambda: MakeOptions.from_keywords(observations=TRAINER_OBSERVATIONS))

    def __post_init__(self) -> None:
        if not self.scenarios:
            raise ValueError("scenarios must name at least one scenario")
        steps = [s for s, _ in self.curriculum]
        if not self.curriculum or steps[0] != 0 or steps != sorted(steps):
            raise ValueError("curriculum must be [[0, n], [step, n], ...] with increasing steps,"
                             f" got {self.curriculum}")
        if any(n < 1 for _, n in self.curriculum):
            raise ValueError(f"curriculum robot counts must be >= 1, got {self.curriculum}")
        max_agents = self.make.robots.max_agents
        if max_agents is not None and max_agents < self.largest_count:
            raise ValueError(f"max_agents {max_agents} is below the curriculum's largest "
                             f"count {self.largest_count}")

    @classmethod
    def from_keys(cls, where: str, values: Mapping[str, Any]) -> EnvSection:
        """From a config section: the section's own keys, the rest ``sgjax.make`` options."""
        own = [f.name for f in dataclasses.fields(cls) if f.name != "make"]
        valid = own + [k for k in KEYWORDS if k != "num_agents"]
        for key in values:
            if key not in valid:
                raise ConfigError(f"{where}: unknown key {key!r}{suggest(str(key), valid)}; "
                                  f"valid keys are: {', '.join(valid)}")
        hints = typing.get_type_hints(cls)
        for key in own:
            if key in values:
                _check_type(f"{where}.{key}", values[key], hints[key])
        options = {k: _freeze(v) for k, v in values.items() if k not in own}
        if not {"observations", "observation_preset"} & set(options):
            options["observations"] = TRAINER_OBSERVATIONS
        try:
            make = MakeOptions.from_keywords(where, **options)
            return cls(make=make, **{k: _freeze(v) for k, v in values.items() if k in own})
        except ValueError as err:
            raise ConfigError(f"{where}: {err}") from None

    def to_dict(self) -> dict[str, Any]:
        """The section as written in a config file (make options that differ from defaults,
        and always the world semantics ``arrived`` / ``ended``, so that a checkpoint keeps the
        world it was trained in when a default changes)."""
        out = {"scenarios": list(self.scenarios), "curriculum": _plain(self.curriculum),
               "preset": self.preset}
        world = {"arrived": self.make.robots.arrived, "ended": self.make.robots.ended}
        return out | world | _plain(self.make.keywords(changed_only=True))

    @property
    def action_mode(self) -> str:
        return self.make.robots.action_mode

    @property
    def largest_count(self) -> int:
        return max(n for _, n in self.curriculum)

    @property
    def slots(self) -> int:
        return self.make.robots.max_agents or self.largest_count

    def make_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``sgjax.make`` (robot counts aside)."""
        kwargs = _thaw(self.make.keywords(changed_only=True))
        kwargs.pop("num_agents", None)
        kwargs.pop("max_agents", None)
        if self.preset is not None:
            kwargs["observations"] = kwargs["rewards"] = self.preset
            kwargs.pop("observation_preset", None)
            kwargs.pop("reward_preset", None)
        return kwargs

    def num_agents_at(self, step: int) -> int:
        """Robot count of the curriculum stage that ``step`` (environment steps) is in."""
        count = self.curriculum[0][1]
        for start, n in self.curriculum:
            if step >= start:
                count = n
        return count


LANE_MODES = ("auto", "batched", "sequential")


@dataclasses.dataclass(frozen=True)
class AlgorithmConfig:
    """PPO. ``total_steps`` counts environment steps over the whole batch (each moves every
    robot of one environment); one update collects ``num_envs x num_steps`` of them."""

    name: str = "ippo"  # ippo (shared actor and critic) or mappo (centralised critic)
    total_steps: int = 3_000_000
    num_envs: int = 256
    num_steps: int = 64
    update_epochs: int = 4
    num_minibatches: int = 4
    learning_rate: float = 3e-4
    anneal_lr: bool = True
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_eps: float = 0.2
    ent_coef: float = 0.01
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    normalize_observations: bool = True
    normalize_rewards: bool = True
    reward_clip: float = 10.0  # after normalisation
    # Share of the team's mean reward in each robot's reward: 0 independent (each its own), 1
    # fully shared (every active robot gets the mean over the robots active that step).
    team_reward: float = 0.0
    # How the lanes of one call (seeds, ablation variants) run the learning phase: "batched"
    # (one vmap: every product gains a lane dimension), "sequential" (one lane after
    # another, each written as a batch of one: 1.7x faster learning on XLA:CPU, see
    # docs/xla-cpu-learning-layout.md), or "auto" (sequential on a CPU, batched elsewhere).
    # Results agree to float rounding.
    lanes: str = "auto"

    def __post_init__(self) -> None:
        if self.name not in ("ippo", "mappo"):
            raise ValueError(f"name must be ippo or mappo, got {self.name!r}")
        if self.lanes not in LANE_MODES:
            raise ValueError(f"lanes must be one of {', '.join(LANE_MODES)}, got {self.lanes!r}")
        for field in ("total_steps", "num_envs", "num_steps", "update_epochs",
                      "num_minibatches"):
            if getattr(self, field) < 1:
                raise ValueError(f"{field} must be >= 1, got {getattr(self, field)}")
        for field in ("gamma", "gae_lambda", "team_reward"):
            if not 0.0 <= getattr(self, field) <= 1.0:
                raise ValueError(f"{field} must be in [0, 1], got {getattr(self, field)}")

    @property
    def steps_per_update(self) -> int:
        return self.num_envs * self.num_steps

    @property
    def num_updates(self) -> int:
        return max(1, self.total_steps // self.steps_per_update)


@dataclasses.dataclass(frozen=True)
class NetworkConfig:
    """Actor and critic: an optional encoder pooling the ``others`` observation block
    (``attention``, or ``lstm`` over the bodies farthest first as in CADRL-LSTM), an optional
    GRU (``kind: gru``, reset at episode ends), then an MLP."""

    kind: str = "mlp"  # mlp or gru
    hidden: tuple[int, ...] = (128, 128)
    activation: str = "tanh"  # tanh or relu
    recurrent_size: int = 128
    others_encoder: str = "none"  # none, attention or lstm
    encoder_size: int = 64
    # One others encoder feeding both the actor and the (decentralised) critic, as SB3 shares
    # its features extractor; False: each tower has its own.
    shared_encoder: bool = False
    agent_id: bool = False  # append a one-hot robot id to the observation

    def __post_init__(self) -> None:
        for field, choices in (("kind", ("mlp", "gru")), ("activation", ("tanh", "relu")),
                               ("others_encoder", ("none", "attention", "lstm"))):
            if getattr(self, field) not in choices:
                raise ValueError(f"{field} must be one of {choices}, got "
                                 f"{getattr(self, field)!r}")
        if not self.hidden or any(h < 1 for h in self.hidden):
            raise ValueError(f"hidden must be a non-empty list of sizes, got {self.hidden}")


@dataclasses.dataclass(frozen=True)
class EvaluationConfig:
    """Periodic evaluation (``every`` environment steps, on the curriculum's current robot
    count; the best checkpoint is kept by team success) and the final one (every count in
    ``num_agents``, beside ``baseline``)."""

    every: int = 1_000_000
    episodes: int = 32
    num_agents: tuple[int, ...] = (3, 4, 5, 7, 10)
    baseline: str | None = "only_local"
    deterministic: bool = False  # greedy actions instead of sampling from the policy
    gif: bool = True

    def __post_init__(self) -> None:
        if self.every < 1 or self.episodes < 1 or not self.num_agents:
            raise ValueError("every and episodes must be >= 1 and num_agents non-empty")


@dataclasses.dataclass(frozen=True)
class LoggingConfig:
    out: str = "runs/train"
    checkpoint_every: int = 500_000  # environment steps between checkpoints
    tensorboard: bool = True
    progress: bool = True

    def __post_init__(self) -> None:
        if self.checkpoint_every < 1:
            raise ValueError(f"checkpoint_every must be >= 1, got {self.checkpoint_every}")


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    env: EnvSection = dataclasses.field(default_factory=EnvSection)
    algorithm: AlgorithmConfig = dataclasses.field(default_factory=AlgorithmConfig)
    network: NetworkConfig = dataclasses.field(default_factory=NetworkConfig)
    evaluation: EvaluationConfig = dataclasses.field(default_factory=EvaluationConfig)
    logging: LoggingConfig = dataclasses.field(default_factory=LoggingConfig)
    seed: int = 0
    num_seeds: int = 1  # trained at once with vmap

    def __post_init__(self) -> None:
        if self.num_seeds < 1:
            raise ValueError(f"num_seeds must be >= 1, got {self.num_seeds}")

    def to_dict(self) -> dict[str, Any]:
        out = _plain(dataclasses.asdict(dataclasses.replace(self, env=EnvSection())))
        return out | {"env": self.env.to_dict()}


SECTIONS = {"env": EnvSection, "algorithm": AlgorithmConfig, "network": NetworkConfig,
            "evaluation": EvaluationConfig, "logging": LoggingConfig}
TOP_LEVEL = ("seed", "num_seeds")


class _ConfigLoader(yaml.SafeLoader):
    """PyYAML's safe loader, reading numbers in exponent form without a dot as YAML 1.2 does
    (PyYAML, YAML 1.1, reads ``2e6`` as text): a whole mantissa with a non-negative exponent
    is an int (``2e6`` is 2000000, as ``2_000_000``), any other (``3e-4``, ``2.5e6``) a float."""


def _exponent_int(loader: _ConfigLoader, node: yaml.ScalarNode) -> int:
    mantissa, _, exponent = loader.construct_scalar(node).replace("_", "").lower().partition("e")
    return int(mantissa) * 10 ** int(exponent)


_EXPONENT_INT = "tag:sgjax,2026:exponent-int"
_ConfigLoader.add_implicit_resolver(  # before the float rule: the first match wins
    _EXPONENT_INT, re.compile(r"^[-+]?[0-9][0-9_]*[eE]\+?[0-9]+$"), list("-+0123456789"))
_ConfigLoader.add_constructor(_EXPONENT_INT, _exponent_int)
_ConfigLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"))


def read_yaml(text: str) -> Any:
    """A config file's or ``--set`` value's YAML; numbers may be written ``2e6``."""
    return yaml.load(text, Loader=_ConfigLoader)  # noqa: S506 (a SafeLoader subclass)


def load_config(path: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> TrainConfig:
    """Read and validate a YAML config; ``overrides`` are ``"section.key=value"`` strings."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: no such config file")
    data = read_yaml(path.read_text()) or {}
    if not isinstance(data, Mapping):
        raise ConfigError(f"{path}: expected a mapping of sections, got {type(data).__name__}")
    return config_from_dict(apply_overrides(data, overrides), str(path))


def apply_overrides(data: Mapping[str, Any], overrides: list[str] | tuple[str, ...]
                    ) -> dict[str, Any]:
    """A copy of a config dict with ``"section.key=value"`` overrides (values read as YAML)."""
    data = {k: dict(v) if isinstance(v, Mapping) else v for k, v in data.items()}
    for item in overrides:
        key, sep, value = item.partition("=")
        if not sep:
            raise ConfigError(f"--set {item!r}: expected section.key=value")
        section, _, field = key.partition(".")
        if field:
            data.setdefault(section, {})
            if not isinstance(data[section], dict):
                raise ConfigError(f"--set {item!r}: {section} is not a section")
            data[section][field] = read_yaml(value)
        else:
            data[section] = read_yaml(value)
    return data


def config_from_dict(data: Mapping[str, Any], source: str = "config") -> TrainConfig:
    valid = list(SECTIONS) + list(TOP_LEVEL)
    sections = {}
    for key, value in data.items():
        if key not in valid:
            raise ConfigError(f"{source}: unknown key {key!r}{suggest(str(key), valid)}; "
                              f"valid keys are: {', '.join(valid)}")
        if key in TOP_LEVEL:
            _check_type(f"{source}: {key}", value, int)
            sections[key] = value
            continue
        if not isinstance(value, Mapping):
            raise ConfigError(f"{source}: section {key!r} must be a mapping, got {value!r}")
        build = EnvSection.from_keys if key == "env" else partial(_build, cls=SECTIONS[key])
        sections[key] = build(f"{source}: {key}", values=value)
    try:
        return TrainConfig(**sections)
    except ValueError as err:
        raise ConfigError(f"{source}: {err}") from None


def _build(where: str, values: Mapping[str, Any], cls: type) -> Any:
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    for key, value in values.items():
        if key not in names:
            raise ConfigError(f"{where}: unknown key {key!r}{suggest(str(key), names)}; "
                              f"valid keys are: {', '.join(names)}")
        _check_type(f"{where}.{key}", value, hints[key])
    try:
        return cls(**{k: _freeze(v) for k, v in values.items()})
    except ValueError as err:
        raise ConfigError(f"{where}: {err}") from None


def _check_type(where: str, value: Any, hint: Any) -> None:
    """Check plain YAML values against simple annotations (Any passes)."""
    if hint is Any:
        return
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        errors = []
        for option in typing.get_args(hint):
            try:
                _check_type(where, value, option)
                return
            except ConfigError as err:
                errors.append(str(err))
        raise ConfigError(f"{where}: expected {_describe(hint)}, got {value!r}")
    if hint is type(None):
        if value is not None:
            raise ConfigError(f"{where}: expected null, got {value!r}")
        return
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ConfigError(f"{where}: expected a list, got {value!r}")
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            for i, item in enumerate(value):
                _check_type(f"{where}[{i}]", item, args[0])
        else:
            if len(value) != len(args):
                raise ConfigError(f"{where}: expected {len(args)} items, got {value!r}")
            for i, (item, arg) in enumerate(zip(value, args, strict=True)):
                _check_type(f"{where}[{i}]", item, arg)
        return
    if hint is bool:
        ok = isinstance(value, bool)
    elif hint is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif hint is float:
        ok = isinstance(value, int | float) and not isinstance(value, bool)
    elif hint is str:
        ok = isinstance(value, str)
    else:
        ok = True
    if not ok:
        raise ConfigError(f"{where}: expected {_describe(hint)}, got {value!r}")


def _describe(hint: Any) -> str:
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        return " or ".join(_describe(a) for a in typing.get_args(hint))
    if hint is type(None):
        return "null"
    return getattr(hint, "__name__", str(hint))


def _freeze(value: Any) -> Any:
    if isinstance(value, list | tuple):
        return tuple(_freeze(v) for v in value)
    if isinstance(value, Mapping):
        return {k: _freeze(v) for k, v in value.items()}
    return value


def _thaw(value: Any) -> Any:
    if isinstance(value, tuple):
        return [_thaw(v) for v in value]
    if isinstance(value, Mapping):
        return {k: _thaw(v) for k, v in value.items()}
    return value


def _plain(value: Any) -> Any:
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    return value
