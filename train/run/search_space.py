"""A hyper-parameter search space file, read and validated (``train.sweep`` runs it).

A space file is YAML with five sections (every key but ``params`` optional)::

    objective:                 # how a trial is scored, on validation episodes
      metric: team_success     # any metric of sgjax's evaluator (docs/metrics.md)
      direction: maximize      # or minimize
      num_agents: [4]          # robot counts; the score is the mean over counts and seeds
      episodes: 64             # validation episodes per robot count and training seed
    trial:
      seeds: 1                 # training seeds per trial, as lanes (seed, seed + 1, ...)
      evaluations: 4           # validation evaluations per trial: the pruner's checkpoints
    sweep:
      trials: 32               # trials in the study (all processes together)
      lanes: 8                 # lanes (trial x seed) trained side by side in one call
      sampler: tpe             # tpe, random or grid (grid: choices only)
      pruner: median           # none, median or hyperband
      seed: 0                  # the sampler's seed
    set:                       # config keys every trial shares, as --set takes them
      algorithm.total_steps: 500000
    params:                    # the space: config key -> distribution, in order
      algorithm.learning_rate: {type: float, low: 1.0e-4, high: 1.0e-3, log: true}
      algorithm.ent_coef: {type: float, low: 0.0, high: 0.03}
      network.kind: {choices: [mlp, gru]}
      network.recurrent_size: {type: int, low: 64, high: 256, step: 64,
                               when: {network.kind: gru}}
      term_weights.collision: {type: float, low: 0.5, high: 2.0}
      hide.others.velocity: {choices: [false, true]}

A parameter is a config key (``section.key``, any key of the training config: ``--set``'s
form), ``term_weights.<reward term>`` (a multiplier on that term of ``info["reward_terms"]``,
1 as configured) or ``hide.<feature>`` (true hides that observation feature, as
``train.ablation``'s ``hide``). ``when`` makes a parameter conditional: it is sampled only in
trials where each named earlier parameter has the given value (or one of a list).

Parameters are of two kinds (:func:`is_lane_key`): **lane values** (``algorithm.`` +
``train.algorithm.lane_settings.LANE_SETTINGS``, reward-term weights, hidden features) are
numbers in the runner state, so trials that differ only in them train as lanes of one compiled
call; every other key changes the compiled program (network sizes, minibatch count,
environments) and trials are grouped by those values, one compilation per group.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from sgjax.terms.base import ConfigError
from sgjax.validation import check_choice, check_keys, freeze, suggest, thaw
from train.algorithm.config import SECTIONS, read_yaml
from train.algorithm.lane_settings import LANE_SETTINGS

SAMPLERS = ("tpe", "random", "grid")
PRUNERS = ("none", "median", "hyperband")
DIRECTIONS = ("maximize", "minimize")
LANE_PREFIXES = ("term_weights", "hide")
TYPES = ("float", "int", "categorical")


@dataclasses.dataclass(frozen=True)
class Param:
    """One dimension of the space: ``kind`` float, int or categorical; ``low``/``high``
    (inclusive), ``log`` and ``step`` for numbers, ``choices`` for a categorical; ``when``
    ``((key, allowed values), ...)``: sampled only where every earlier ``key`` took one of
    its allowed values."""

    key: str
    kind: str
    low: float | None = None
    high: float | None = None
    log: bool = False
    step: float | None = None
    choices: tuple[Any, ...] = ()
    when: tuple[tuple[str, tuple[Any, ...]], ...] = ()

    def to_optuna(self, value: Any) -> Any:
        """A choice as Optuna stores it: a list as its JSON text (Optuna's categoricals are
        numbers, text, booleans and None)."""
        return json.dumps(thaw(value)) if isinstance(value, tuple) else value

    def from_optuna(self, value: Any) -> Any:
        """:meth:`to_optuna` undone (a list choice back from its text)."""
        if isinstance(value, str) and any(isinstance(c, tuple) for c in self.choices):
            for choice in self.choices:
                if self.to_optuna(choice) == value:
                    return thaw(choice)
        return value

    def applies(self, values: Mapping[str, Any]) -> bool:
        """Whether this parameter is sampled, given the values sampled before it."""
        return all(key in values and values[key] in allowed for key, allowed in self.when)


@dataclasses.dataclass(frozen=True)
class Objective:
    metric: str = "team_success"
    direction: str = "maximize"
    num_agents: tuple[int, ...] = (4,)
    episodes: int = 64


@dataclasses.dataclass(frozen=True)
class SearchSpace:
    """A parsed space file (see the module docstring); ``source`` names it in errors."""

    params: tuple[Param, ...]
    objective: Objective = Objective()
    seeds: int = 1
    evaluations: int = 4
    trials: int = 32
    lanes: int = 8
    sampler: str = "tpe"
    pruner: str = "median"
    sampler_seed: int = 0
    settings: tuple[tuple[str, Any], ...] = ()  # (section.key, value) for every trial
    source: str = "space"

    def replace(self, **changes: Any) -> SearchSpace:
        space = dataclasses.replace(self, **changes)
        _check_counts(space)
        return space

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(p.key for p in self.params)

    def to_dict(self) -> dict[str, Any]:
        """The space as a file holds it (plain YAML data)."""
        params = {}
        for p in self.params:
            entry: dict[str, Any] = ({"choices": thaw(p.choices)} if p.kind == "categorical"
                                     else {"type": p.kind, "low": p.low, "high": p.high})
            if p.log:
                entry["log"] = True
            if p.step is not None:
                entry["step"] = p.step
            if p.when:
                entry["when"] = {k: thaw(v) if len(v) > 1 else thaw(v[0]) for k, v in p.when}
            params[p.key] = entry
        o = self.objective
        return {"objective": {"metric": o.metric, "direction": o.direction,
                              "num_agents": list(o.num_agents), "episodes": o.episodes},
                "trial": {"seeds": self.seeds, "evaluations": self.evaluations},
                "sweep": {"trials": self.trials, "lanes": self.lanes, "sampler": self.sampler,
                          "pruner": self.pruner, "seed": self.sampler_seed},
                "set": dict(self.settings), "params": params}


def is_lane_key(key: str) -> bool:
    """Whether trials differing in ``key`` can share one compiled call (see the module
    docstring)."""
    section, _, field = key.partition(".")
    return section in LANE_PREFIXES or (section == "algorithm" and field in LANE_SETTINGS)


def load_space(path: str | Path) -> SearchSpace:
    """A space file, validated; errors are ``ConfigError`` naming the file and the key."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: no such search space file")
    try:
        data = read_yaml(path.read_text())
    except yaml.YAMLError as err:
        raise ConfigError(f"{path}: not YAML ({err})") from None
    return space_from_dict(data, str(path))


def space_from_dict(data: Any, source: str = "space") -> SearchSpace:
    """A validated :class:`SearchSpace` from plain data (a space file's)."""
    if not isinstance(data, Mapping):
        raise ConfigError(f"{source}: expected a mapping with objective, trial, sweep, set and "
                          "params")
    try:
        check_keys(source, data, ["objective", "trial", "sweep", "set", "params"])
        objective = _objective(f"{source}: objective", _section(source, data, "objective"))
        trial = _section(source, data, "trial")
        check_keys(f"{source}: trial", trial, ["seeds", "evaluations"])
        sweep = _section(source, data, "sweep")
        check_keys(f"{source}: sweep", sweep, ["trials", "lanes", "sampler", "pruner", "seed"])
        settings = _section(source, data, "set")
        for key in settings:
            _check_config_key(f"{source}: set: {key}", key)
        params = _params(source, data.get("params"))
        sampler = sweep.get("sampler", "tpe")
        check_choice(f"{source}: sweep.sampler", sampler, SAMPLERS)
        pruner = sweep.get("pruner", "median")
        check_choice(f"{source}: sweep.pruner", pruner, PRUNERS)
        space = SearchSpace(
            params=params, objective=objective,
            seeds=_count(f"{source}: trial.seeds", trial.get("seeds", 1)),
            evaluations=_count(f"{source}: trial.evaluations", trial.get("evaluations", 4)),
            trials=_count(f"{source}: sweep.trials", sweep.get("trials", 32)),
            lanes=_count(f"{source}: sweep.lanes", sweep.get("lanes", 8)),
            sampler=sampler, pruner=pruner,
            sampler_seed=_count(f"{source}: sweep.seed", sweep.get("seed", 0), low=0),
            settings=tuple((str(k), freeze(v)) for k, v in settings.items()), source=source)
        if sampler == "grid":
            for p in params:
                if p.kind != "categorical" or p.when:
                    raise ValueError(f"{source}: params: {p.key}: the grid sampler takes "
                                     "unconditional choices only")
        _check_counts(space)
        return space
    except ConfigError:
        raise
    except ValueError as err:
        raise ConfigError(str(err)) from None


def _check_counts(space: SearchSpace) -> None:
    if space.lanes % space.seeds:
        raise ConfigError(f"{space.source}: sweep.lanes ({space.lanes}) must be a multiple of "
                          f"trial.seeds ({space.seeds}): a trial trains its seeds side by side")


def _section(source: str, data: Mapping[str, Any], name: str) -> Mapping[str, Any]:
    value = data.get(name) or {}
    if not isinstance(value, Mapping):
        raise ValueError(f"{source}: {name} must be a mapping, got {value!r}")
    return value


def _count(where: str, value: Any, low: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise ValueError(f"{where} must be an integer >= {low}, got {value!r}")
    return value


def _objective(where: str, values: Mapping[str, Any]) -> Objective:
    check_keys(where, values, ["metric", "direction", "num_agents", "episodes"])
    from sgjax.evaluation.metrics import METRICS

    metric = values.get("metric", "team_success")
    if not isinstance(metric, str) or metric not in METRICS:
        raise ValueError(f"{where}.metric: unknown metric {metric!r}"
                         f"{suggest(str(metric), list(METRICS.names()))}")
    direction = values.get("direction", "maximize")
    check_choice(f"{where}.direction", direction, DIRECTIONS)
    counts = values.get("num_agents", [4])
    if isinstance(counts, int):
        counts = [counts]
    if not isinstance(counts, Sequence) or not counts:
        raise ValueError(f"{where}.num_agents: expected a robot count or a list of them")
    counts = tuple(_count(f"{where}.num_agents", n) for n in counts)
    return Objective(metric=metric, direction=direction, num_agents=counts,
                     episodes=_count(f"{where}.episodes", values.get("episodes", 64)))


def _check_config_key(where: str, key: str) -> None:
    """``key`` is ``section.key`` of the training config, or a lane key."""
    section, dot, field = key.partition(".")
    if not dot or not field:
        raise ValueError(f"{where}: expected section.key (algorithm.learning_rate), "
                         "term_weights.<reward term> or hide.<feature>")
    if section in LANE_PREFIXES:
        return  # checked against the trainer's reward terms and observation columns
    if section in ("seed", "num_seeds"):
        raise ValueError(f"{where}: seeds are the sweep's (trial.seeds), not a parameter")
    if section not in SECTIONS:
        raise ValueError(f"{where}: unknown config section {section!r}"
                         f"{suggest(section, [*SECTIONS, *LANE_PREFIXES])}")
    if section != "env":  # env keys are sgjax.make's options too; the config checks them
        names = [f.name for f in dataclasses.fields(SECTIONS[section])]
        if field not in names:
            raise ValueError(f"{where}: {section} has no key {field!r}{suggest(field, names)}")


def _params(source: str, data: Any) -> tuple[Param, ...]:
    where = f"{source}: params"
    if not isinstance(data, Mapping) or not data:
        raise ValueError(f"{where}: expected a mapping of config keys to distributions")
    params: list[Param] = []
    for key, spec in data.items():
        key = str(key)
        at = f"{where}: {key}"
        _check_config_key(at, key)
        if not isinstance(spec, Mapping):
            raise ValueError(f"{at}: expected {{type: float, low: .., high: ..}}, "
                             "{type: int, ...} or {choices: [...]}")
        check_keys(at, spec, ["type", "low", "high", "log", "step", "choices", "when"])
        kind = spec.get("type", "categorical" if "choices" in spec else None)
        if kind is None:
            raise ValueError(f"{at}: give type (float or int) with low and high, or choices")
        check_choice(f"{at}.type", kind, TYPES)
        when = _when(at, spec.get("when"), params)
        if kind == "categorical":
            choices = spec.get("choices")
            if not isinstance(choices, Sequence) or isinstance(choices, str) or not choices:
                raise ValueError(f"{at}.choices: expected a non-empty list")
            if any(isinstance(c, Mapping) or (isinstance(c, list) and any(
                    isinstance(x, Mapping | list) for x in c)) for c in choices):
                raise ValueError(f"{at}.choices: each choice must be a number, text, true/false,"
                                 " null or a list of them")
            if key.startswith("hide.") and not all(isinstance(c, bool) for c in choices):
                raise ValueError(f"{at}.choices: a hidden feature is true or false")
            extra = sorted(set(spec) - {"type", "choices", "when"})
            if extra:
                raise ValueError(f"{at}: {', '.join(extra)} apply to numbers, not choices")
            params.append(Param(key, kind, choices=tuple(freeze(c) for c in choices),
                                when=when))
            continue
        if key.startswith("hide."):
            raise ValueError(f"{at}: a hidden feature takes choices: [false, true]")
        low, high = spec.get("low"), spec.get("high")
        number = int if kind == "int" else (int, float)
        for name, value in (("low", low), ("high", high)):
            if isinstance(value, bool) or not isinstance(value, number) or not math.isfinite(
                    value):
                raise ValueError(f"{at}.{name}: expected a{'n integer' if kind == 'int' else ''}"
                                 f" number, got {value!r}")
        if low > high:
            raise ValueError(f"{at}: low ({low}) is above high ({high})")
        log = spec.get("log", False)
        if not isinstance(log, bool):
            raise ValueError(f"{at}.log: expected true or false, got {log!r}")
        if log and low <= 0:
            raise ValueError(f"{at}: a log scale needs low > 0, got {low}")
        step = spec.get("step")
        if step is not None:
            if isinstance(step, bool) or not isinstance(step, number) or step <= 0:
                raise ValueError(f"{at}.step: expected a positive number, got {step!r}")
            if log:
                raise ValueError(f"{at}: step and log cannot be combined")
        params.append(Param(key, kind, low=low, high=high, log=log, step=step, when=when))
    return tuple(params)


def _when(at: str, value: Any, earlier: Sequence[Param]) -> tuple[tuple[str, tuple], ...]:
    if value is None:
        return ()
    if not isinstance(value, Mapping) or not value:
        raise ValueError(f"{at}.when: expected a mapping of earlier parameters to values")
    known = {p.key: p for p in earlier}
    out = []
    for key, allowed in value.items():
        if key not in known:
            raise ValueError(f"{at}.when: {key!r} is not a parameter listed before this one"
                             f"{suggest(str(key), list(known))}")
        allowed = (tuple(freeze(a) for a in allowed)
                   if isinstance(allowed, list) and known[key].kind != "categorical"
                   or (isinstance(allowed, list) and not any(isinstance(c, tuple) for c in
                                                            known[key].choices))
                   else (freeze(allowed),))
        if known[key].kind == "categorical":
            missing = [a for a in allowed if a not in known[key].choices]
            if missing:
                raise ValueError(f"{at}.when: {key} never takes {missing}; its choices are "
                                 f"{list(known[key].choices)}")
        out.append((str(key), allowed))
    return tuple(out)


def suggest_values(trial: Any, space: SearchSpace) -> dict[str, Any]:
    """Sample one trial's parameters from an Optuna ``trial`` (define-by-run: conditional
    parameters only where their ``when`` holds). Returns ``{key: value}``."""
    values: dict[str, Any] = {}
    for p in space.params:
        if not p.applies(values):
            continue
        if p.kind == "categorical":
            values[p.key] = p.from_optuna(trial.suggest_categorical(
                p.key, [p.to_optuna(c) for c in p.choices]))
        elif p.kind == "int":
            values[p.key] = trial.suggest_int(p.key, int(p.low), int(p.high),
                                              step=int(p.step or 1), log=p.log)
        else:
            values[p.key] = trial.suggest_float(p.key, float(p.low), float(p.high),
                                                step=p.step, log=p.log)
    return values


def grid(space: SearchSpace) -> dict[str, list[Any]]:
    """The grid sampler's search space: every parameter's choices (as Optuna stores them)."""
    return {p.key: [p.to_optuna(c) for c in p.choices] for p in space.params}


def trial_values(space: SearchSpace, params: Mapping[str, Any]) -> dict[str, Any]:
    """A stored trial's ``params`` as config values (list choices back from their text)."""
    by_key = {p.key: p for p in space.params}
    return {k: by_key[k].from_optuna(v) if k in by_key else v for k, v in params.items()}


def split_values(values: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """A trial's values as ``(lane values, program settings)`` (:func:`is_lane_key`)."""
    lane = {k: v for k, v in values.items() if is_lane_key(k)}
    return lane, {k: v for k, v in values.items() if not is_lane_key(k)}
