"""Training configuration: YAML files validated into frozen dataclasses.

A config file has the sections ``env``, ``algorithm``, ``network``, ``evaluation``,
``levels`` (a curriculum over generated worlds) and ``logging`` plus ``seed`` and
``num_seeds`` (see ``train/configs/doorway.yaml``, and ``docs/training.md`` for every key
and the SocialGym 2.0 key it replaces). Unknown keys and bad values are errors naming the
file, the key and the nearest valid key. ``--set a.b=value`` on the command line overrides
one key (the value is read as YAML).
"""

from __future__ import annotations

import dataclasses
import math
import re
import typing
from collections.abc import Mapping
from functools import partial
from pathlib import Path
from typing import Any

import yaml

from sgjax.environment.options import KEYWORDS, MakeOptions
from sgjax.evaluation.protocols import PAPER
from sgjax.terms.base import ConfigError
from sgjax.validation import (
    FrozenDict,
    check_choice,
    check_int,
    check_keys,
    check_positive,
    check_range,
    check_type,
    freeze,
    thaw,
)

TRAINER_OBSERVATIONS = "navigation"  # the trainer's default observation preset
# sgjax.make's robot counts: the curriculum's and the section's max_agents, not options.
COUNTS = ("num_agents", "max_agents")


def _trainer_options() -> MakeOptions:
    return MakeOptions.from_keywords(observations=TRAINER_OBSERVATIONS)


@dataclasses.dataclass(frozen=True)
class EnvSection:
    """What to train on: the scenarios, the robot-count curriculum, the robot slots, and the
    options of ``sgjax.make`` (``options``, a :class:`~sgjax.environment.options.MakeOptions`
    that goes to ``make(scenario, options=...)`` as it is).

    In a config file every option of ``sgjax.make`` is a key of the same name (``action_mode``,
    ``robots``, ``observations``, ``rewards``, ``num_humans``, ``dt``, ``num_arcs``, ...),
    validated by the same code; an ``options`` key may hold them nested by group instead
    (``{robots: {...}, humans: {...}, terms: {...}, physics: {...}}``, the form
    :meth:`to_dict` writes and checkpoints store), with any flat key on top. ``curriculum`` is
    ``[[env_step, num_agents], ...]``: from each total environment step on, episodes have that
    many robots (SocialGym's ``agents_settings``), so ``num_agents`` itself is not a key;
    ``max_agents`` (the robot slots) defaults to the curriculum's largest count. ``preset``
    sets the observation and reward presets at once (cadrl, enforced_order); observations
    default to ``navigation``."""

    scenarios: tuple[str, ...] = ("doorway",)
    curriculum: tuple[tuple[int, int], ...] = ((0, 4),)
    preset: str | None = None
    max_agents: int | None = None
    options: MakeOptions = dataclasses.field(default_factory=_trainer_options)

    def __post_init__(self) -> None:
        if not self.scenarios:
            raise ValueError("scenarios must name at least one scenario")
        steps = [s for s, _ in self.curriculum]
        if not self.curriculum or steps[0] != 0 or steps != sorted(steps):
            raise ValueError("curriculum must be [[0, n], [step, n], ...] with increasing steps,"
                             f" got {self.curriculum}")
        for i, (_, n) in enumerate(self.curriculum):
            check_int(f"curriculum[{i}] robot count", n)
        if self.max_agents is not None:
            check_int("max_agents", self.max_agents)
            if self.max_agents < self.largest_count:
                raise ValueError(f"max_agents {self.max_agents} is below the curriculum's "
                                 f"largest count {self.largest_count}")
        robots, defaults = self.options.robots, MakeOptions().robots
        for name in COUNTS:
            if getattr(robots, name) != getattr(defaults, name):
                raise ValueError(f"options.robots.{name} must be left at its default "
                                 f"({getattr(defaults, name)!r}): the robot counts are "
                                 "curriculum and max_agents")
        if self.preset is not None:
            object.__setattr__(self, "options", self.options.replace(
                observations=self.preset, rewards=self.preset, observation_preset=None,
                reward_preset=None))

    @classmethod
    def from_keys(cls, where: str, values: Mapping[str, Any]) -> EnvSection:
        """From a config section: the section's own keys, ``options`` (nested by group) and
        flat ``sgjax.make`` options on top of it."""
        own = ["scenarios", "curriculum", "preset", "max_agents"]
        flat = [k for k in KEYWORDS if k not in COUNTS]
        hints = typing.get_type_hints(cls)
        try:
            check_keys(where, values, own + ["options"] + flat)
            for key in own:
                if key in values:
                    check_type(f"{where}.{key}", values[key], hints[key])
            options = MakeOptions.from_dict(freeze(values.get("options", {})),
                                            f"{where}.options")
            changes = {k: freeze(v) for k, v in values.items() if k in flat}
            nested = {k for group in values.get("options", {}).values() for k in group}
            if not {"observations", "observation_preset"} & (set(changes) | nested):
                changes["observations"] = TRAINER_OBSERVATIONS
            return cls(options=options.replace(where, **changes),
                       **{k: freeze(v) for k, v in values.items() if k in own})
        except ValueError as err:
            raise ConfigError(_located(where, err)) from None

    def to_dict(self) -> dict[str, Any]:
        """The section as written in a config file, with every ``sgjax.make`` option nested
        by group (``options``), defaults included: a checkpoint keeps the world it was
        trained in when a default changes."""
        return {"scenarios": list(self.scenarios), "curriculum": thaw(self.curriculum),
                "preset": self.preset, "max_agents": self.max_agents,
                "options": self.options.to_dict()}

    @property
    def action_mode(self) -> str:
        return self.options.robots.action_mode

    @property
    def largest_count(self) -> int:
        return max(n for _, n in self.curriculum)

    @property
    def slots(self) -> int:
        return self.max_agents or self.largest_count

    def num_agents_at(self, step: int) -> int:
        """Robot count of the curriculum stage that ``step`` (environment steps) is in."""
        count = self.curriculum[0][1]
        for start, n in self.curriculum:
            if step >= start:
                count = n
        return count


LANE_MODES = ("auto", "batched", "sequential")
ALGORITHMS = ("ippo", "mappo")


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
    # another, each written as a batch of one: XLA:CPU lays a batch of one out better, see
    # docs/xla-cpu-learning-layout.md), or "auto" (sequential on a CPU, batched elsewhere).
    # Results agree to float rounding.
    lanes: str = "auto"
    # The learning phase computes only the transitions that can learn: each minibatch's
    # active rows (MLP networks; whole agent sequences with an active step for a GRU) in
    # chunks whose gradients add up to the masked minibatch's, so inactive robot slots
    # (absent, settled, parked) cost no FLOPs. The same minibatches, losses and optimiser
    # steps as False (the masked path) up to float rounding (docs/training.md). "auto": on a
    # CPU, masked elsewhere (a GPU wants the large masked products, not the compacted
    # chunks: docs/benchmark.md, "On a GPU").
    compact: bool | str = "auto"
    # Multipliers on the reward terms the trainer sums (``info["reward_terms"]``: the
    # environment's reward terms and the enders that pay, such as stuck), {term: factor}; a
    # term not named keeps 1. Numbers of the runner state, not of the compiled program:
    # train.sweep tunes them as lanes, train.ablation switches terms off (factor 0).
    term_weights: Mapping[str, float] = dataclasses.field(default_factory=FrozenDict)
    # Observation features the networks never see (zeroed in every observation): a term
    # ("velocity") or "<term>.<feature>" ("others.velocity", "pose.heading"), as
    # train.ablation's hide; checked against the observation's columns when training starts.
    hide: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        check_choice("name", self.name, ALGORITHMS)
        if not isinstance(self.term_weights, Mapping):
            raise ValueError(f"term_weights must be a mapping of reward terms to factors, got "
                             f"{self.term_weights!r}")
        for term, factor in self.term_weights.items():
            if not isinstance(term, str) or isinstance(factor, bool) or not isinstance(
                    factor, int | float) or not math.isfinite(factor):
                raise ValueError(f"term_weights.{term}: expected a finite number, got "
                                 f"{factor!r}")
        object.__setattr__(self, "term_weights", freeze(dict(self.term_weights)))
        check_choice("lanes", self.lanes, LANE_MODES)
        if not (isinstance(self.compact, bool) or self.compact == "auto"):  # 1 == True
            raise ValueError(f"compact must be true, false or 'auto', got {self.compact!r}")
        for field in ("total_steps", "num_envs", "num_steps", "update_epochs",
                      "num_minibatches"):
            check_int(field, getattr(self, field))
        for field in ("gamma", "gae_lambda", "team_reward"):
            check_range(field, getattr(self, field), 0.0, 1.0)
        for field in ("learning_rate", "clip_eps", "max_grad_norm", "reward_clip"):
            check_positive(field, getattr(self, field))
        for field in ("ent_coef", "vf_coef"):
            check_positive(field, getattr(self, field), allow_zero=True)

    @property
    def steps_per_update(self) -> int:
        return self.num_envs * self.num_steps

    @property
    def num_updates(self) -> int:
        return max(1, self.total_steps // self.steps_per_update)


def resolved_compact(value: bool | str, backend: str) -> bool:
    """``algorithm.compact`` as a trainer on ``backend`` (``jax.default_backend()``) runs it:
    ``"auto"`` is the compacted learning phase on a CPU, the masked one elsewhere."""
    return value is True or (value == "auto" and backend == "cpu")


def resolved_lanes(value: str, backend: str) -> str:
    """``algorithm.lanes`` as a trainer on ``backend`` runs it: ``"auto"`` is sequential on a
    CPU, batched elsewhere."""
    return value if value != "auto" else ("sequential" if backend == "cpu" else "batched")


def as_trained(config: dict[str, Any], backend: str | None = None) -> dict[str, Any]:
    """A config dict (``TrainConfig.to_dict()``) with ``algorithm.compact`` written as a trainer
    on ``backend`` (default this process's) runs it, for comparing a saved run with a new one:
    a run saved when the default was ``true`` matches ``"auto"`` on a CPU, where the
    computation is the same (``train.reproduce --resume``, ``train.ablation --resume``)."""
    import jax

    backend = backend or jax.default_backend()
    algorithm = dict(config["algorithm"])
    algorithm["compact"] = resolved_compact(algorithm.get("compact", True), backend)
    return {**config, "algorithm": algorithm}


NETWORK_KINDS = ("mlp", "gru", "lstm")


@dataclasses.dataclass(frozen=True)
class NetworkConfig:
    """Actor and critic: an optional encoder pooling the ``others`` observation block
    (``attention``, or ``lstm`` over the bodies farthest first as in CADRL-LSTM), an optional
    memory over time (``kind: gru`` or ``lstm``, reset at episode ends; ``lstm`` is LSTM-PPO
    as sb3-contrib's RecurrentPPO builds it, an actor LSTM and a critic LSTM), then an MLP."""

    # mlp; gru (a dense layer, then a GRU over time); lstm (an LSTM over time on the
    # observation, then the MLP: sb3-contrib's MlpLstmPolicy, LSTM-PPO)
    kind: str = "mlp"
    hidden: tuple[int, ...] = (128, 128)
    activation: str = "tanh"  # tanh or relu
    recurrent_size: int = 128
    others_encoder: str = "none"  # none, attention or lstm
    encoder_size: int = 64
    # One others encoder feeding both the actor and the (decentralised) critic, as SB3 shares
    # its features extractor; False: each tower has its own.
    shared_encoder: bool = False
    agent_id: bool = False  # append a one-hot robot id to the observation

    @property
    def recurrent(self) -> bool:
        """Whether the network keeps a memory over time (``gru`` or ``lstm``)."""
        return self.kind != "mlp"

    def __post_init__(self) -> None:
        for field, choices in (("kind", NETWORK_KINDS), ("activation", ("tanh", "relu")),
                               ("others_encoder", ("none", "attention", "lstm"))):
            check_choice(field, getattr(self, field), choices)
        if not self.hidden:
            raise ValueError(f"hidden must be a non-empty list of sizes, got {self.hidden}")
        for i, size in enumerate(self.hidden):
            check_int(f"hidden[{i}]", size)


CHECKPOINTS = ("final", "best")


@dataclasses.dataclass(frozen=True)
class EvaluationConfig:
    """Periodic evaluation (``every`` environment steps, on the curriculum's current robot
    count, on the validation episodes; the best checkpoint by mean team success is kept) and
    the final one (every count in ``num_agents``, beside ``baseline``) of the weights
    ``checkpoint`` names: ``final`` (the default, the rule of every sgjax command: the weights
    training ended with) or ``best`` (the best periodic evaluation's, as SocialGym 2.0's
    ``ending_eval_with_best`` did)."""

    every: int = 1_000_000
    episodes: int = 32
    num_agents: tuple[int, ...] = PAPER.num_agents  # the paper's robot counts
    baseline: str | None = "only_local"
    deterministic: bool = False  # greedy actions instead of sampling from the policy
    gif: bool = True
    checkpoint: str = "final"  # which weights the final evaluation judges: final or best

    def __post_init__(self) -> None:
        check_choice("checkpoint", self.checkpoint, CHECKPOINTS)
        check_int("every", self.every)
        check_int("episodes", self.episodes)
        if not self.num_agents:
            raise ValueError("num_agents must name at least one robot count")
        for i, n in enumerate(self.num_agents):
            check_int(f"num_agents[{i}]", n)


CURRICULA = ("dr", "plr", "accel", "learnability")


@dataclasses.dataclass(frozen=True)
class LevelsConfig:
    """The curriculum over generated worlds (scenarios ``generated:<family>``;
    :mod:`train.algorithm.level_buffer`). ``dr``: domain randomisation, a fresh world at every
    episode. ``plr``: prioritised level replay (a buffer of ``buffer_size`` levels per family,
    scored by positive value loss; an environment replays one with probability
    ``replay_prob`` once the buffer is ``min_fill`` full, sampled by rank with
    ``temperature`` and by staleness with weight ``staleness``). ``accel``: PLR whose replays
    are edited with probability ``mutate_prob`` (``edits`` changes, each a parameter moved by
    up to ``edit_scale`` of its range or, in an environment with room for more pedestrians
    (``max_humans`` above ``num_humans``), a group of ``pedestrian_group`` of them added; 0:
    never). ``learnability``: PLR's buffer scored by ``p (1 - p)``, p the
    level's robot success (SFL)."""

    method: str = "dr"
    buffer_size: int = 256
    replay_prob: float = 0.5
    min_fill: float = 0.5
    temperature: float = 0.3
    staleness: float = 0.3
    mutate_prob: float = 0.5
    edits: int = 1
    edit_scale: float = 0.2
    pedestrian_group: int = 2

    def __post_init__(self) -> None:
        check_choice("method", self.method, CURRICULA)
        check_int("buffer_size", self.buffer_size)
        check_int("edits", self.edits)
        check_int("pedestrian_group", self.pedestrian_group, 0)
        for name in ("replay_prob", "min_fill", "staleness", "mutate_prob", "edit_scale"):
            check_range(name, getattr(self, name), 0.0, 1.0)
        check_positive("temperature", self.temperature)

    @property
    def active(self) -> bool:
        """Whether the trainer picks worlds (every method but ``dr``)."""
        return self.method != "dr"

    def lane_values(self, method: str | None = None) -> dict[str, float]:
        """The numbers a lane's curriculum reads (``RunnerState.curriculum``) for ``method``
        (default this config's) with this config's settings: ``replay_prob`` (0 under
        ``dr``: the buffer is kept but never replayed), ``mutate_prob`` (0 but under
        ``accel``) and ``learnability`` (1 under ``learnability``: the buffer's score). So
        lanes of one program may follow different methods (``train.ablation``)."""
        method = self.method if method is None else method
        check_choice("levels.method", method, CURRICULA)
        return {"replay_prob": 0.0 if method == "dr" else self.replay_prob,
                "mutate_prob": self.mutate_prob if method == "accel" else 0.0,
                "learnability": 1.0 if method == "learnability" else 0.0}


@dataclasses.dataclass(frozen=True)
class LoggingConfig:
    out: str = "runs/train"
    checkpoint_every: int = 500_000  # environment steps between checkpoints
    tensorboard: bool = True
    progress: bool = True

    def __post_init__(self) -> None:
        check_int("checkpoint_every", self.checkpoint_every)


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    env: EnvSection = dataclasses.field(default_factory=EnvSection)
    algorithm: AlgorithmConfig = dataclasses.field(default_factory=AlgorithmConfig)
    network: NetworkConfig = dataclasses.field(default_factory=NetworkConfig)
    evaluation: EvaluationConfig = dataclasses.field(default_factory=EvaluationConfig)
    levels: LevelsConfig = dataclasses.field(default_factory=LevelsConfig)
    logging: LoggingConfig = dataclasses.field(default_factory=LoggingConfig)
    seed: int = 0
    num_seeds: int = 1  # trained at once with vmap

    def __post_init__(self) -> None:
        check_int("num_seeds", self.num_seeds)

    def to_dict(self) -> dict[str, Any]:
        """The config as a file holds it (plain YAML data; :func:`config_from_dict` reads it
        back)."""
        out = {f.name: thaw(dataclasses.asdict(getattr(self, f.name)))
               if dataclasses.is_dataclass(getattr(self, f.name)) else getattr(self, f.name)
               for f in dataclasses.fields(self) if f.name != "env"}
        return {"env": self.env.to_dict()} | out


SECTIONS = {"env": EnvSection, "algorithm": AlgorithmConfig, "network": NetworkConfig,
            "evaluation": EvaluationConfig, "levels": LevelsConfig, "logging": LoggingConfig}
# The evaluations of train.reproduce and train.ablation play the episodes of key
# ``seed + EVALUATION_SEED_OFFSET``: never one of the training lanes' keys (``seed + i``, i below
# the number of seeds).
EVALUATION_SEED_OFFSET = 1000
# The validation evaluations' key (the periodic evaluation that picks the best checkpoint, and
# train.sweep's objective): episodes that the final evaluation (key ``seed +
# EVALUATION_SEED_OFFSET``) never plays.
VALIDATION_SEED = 1234

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
    try:
        data = read_yaml(path.read_text()) or {}
    except yaml.YAMLError as err:
        raise ConfigError(f"{path}: not YAML ({err})") from None
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
        try:
            parsed = read_yaml(value)
        except yaml.YAMLError as err:
            raise ConfigError(f"--set {item!r}: the value is not YAML ({err})") from None
        if field:
            data.setdefault(section, {})
            if not isinstance(data[section], dict):
                raise ConfigError(f"--set {item!r}: {section} is not a section")
            data[section][field] = parsed
        else:
            data[section] = parsed
    return data


def config_from_dict(data: Mapping[str, Any], source: str = "config") -> TrainConfig:
    """A validated config from plain data (a config file's or :meth:`TrainConfig.to_dict`'s);
    errors are ``ConfigError`` naming ``source``, the key and the value."""
    valid = list(SECTIONS) + list(TOP_LEVEL)
    sections = {}
    if not isinstance(data, Mapping):
        raise ConfigError(f"{source}: expected a mapping of sections, got {data!r}")
    try:
        check_keys(source, data, valid)
        for key, value in data.items():
            if key in TOP_LEVEL:
                check_type(f"{source}: {key}", value, int)
                sections[key] = value
                continue
            if not isinstance(value, Mapping):
                raise ValueError(f"{source}: section {key!r} must be a mapping, got {value!r}")
            build = EnvSection.from_keys if key == "env" else partial(_build, cls=SECTIONS[key])
            sections[key] = build(f"{source}: {key}", values=value)
        return TrainConfig(**sections)
    except ConfigError:
        raise
    except ValueError as err:
        raise ConfigError(_located(source, err)) from None


def _located(where: str, err: Exception) -> str:
    """An error's message, with ``where`` in front unless it names it already."""
    return str(err) if str(err).startswith(where) else f"{where}: {err}"


def _build(where: str, values: Mapping[str, Any], cls: type) -> Any:
    """``cls(**values)`` for a section: unknown keys, wrong types and bad values are
    ``ConfigError`` naming ``where`` and the key."""
    hints = typing.get_type_hints(cls)
    try:
        check_keys(where, values, [f.name for f in dataclasses.fields(cls)])
        for key, value in values.items():
            check_type(f"{where}.{key}", value, hints[key])
        return cls(**{k: freeze(v) for k, v in values.items()})
    except ValueError as err:
        raise ConfigError(_located(where, err)) from None
