"""Evaluation protocols: named, seed-pinned settings so two users get the same numbers.

A protocol fixes what an evaluation runs (scenarios, robot counts, episodes per
configuration, the evaluation seed, the time limit, whether the counterfactual lanes run);
the policies are the user's. ``sgjax evaluate --protocol paper --policy only_local orca`` runs
the built-in :data:`PAPER`; ``--protocol my_protocol.yaml`` reads a file with the same keys::

    name: my_protocol
    scenarios: [doorway, hallway]
    num_agents: [3, 4, 5]
    episodes: 25
    seed: 0
    counterfactual: true
    time_limit: 75.0   # s; null: the scenario's default
    num_humans: 300    # pedestrians per episode; null: the scenario's
    human_range: 3.0   # m: bodies farther away do not act on a pedestrian; null: every body

Every key is required except ``time_limit``, ``num_humans`` and ``human_range``; unknown keys
are an error naming the file. ``protocols/`` at the repository's root holds shipped protocol
files (``building.yaml``: SocialGym 2.0's GDC floors among hundreds of pedestrians).
"""

from __future__ import annotations

import dataclasses
import typing
from pathlib import Path
from typing import Any

import yaml

from sgjax.environment.options import MakeOptions
from sgjax.validation import check_int, check_positive, check_type, suggest


@dataclasses.dataclass(frozen=True)
class Protocol:
    """What an evaluation runs. ``time_limit`` (s) None: the scenario's default (75 s)."""

    name: str
    scenarios: tuple[str, ...]
    num_agents: tuple[int, ...]
    episodes: int
    seed: int
    counterfactual: bool
    time_limit: float | None = None
    num_humans: int | None = None
    human_range: float | None = None

    def __post_init__(self) -> None:
        where = f"protocol {self.name!r}"
        try:
            for field, hint in typing.get_type_hints(Protocol).items():
                check_type(field, getattr(self, field), hint)
            if not self.scenarios or not self.num_agents:
                raise ValueError("scenarios and num_agents must not be empty")
            for i, n in enumerate(self.num_agents):
                check_int(f"num_agents[{i}]", n)
            check_int("episodes", self.episodes)
            if self.time_limit is not None:
                check_positive("time_limit", self.time_limit)
            if self.num_humans is not None:
                check_int("num_humans", self.num_humans, low=0)
            if self.human_range is not None:
                check_positive("human_range", self.human_range)
        except ValueError as err:
            raise ValueError(f"{where}: {err}") from None

    def options(self, options: MakeOptions | None = None) -> MakeOptions:
        """``options`` (default: ``MakeOptions()``) with the ``sgjax.make`` settings the
        protocol fixes (its time limit, when it names one)."""
        options = options or MakeOptions()
        fixed = {k: v for k, v in (("time_limit", self.time_limit),
                                   ("num_humans", self.num_humans),
                                   ("human_range", self.human_range)) if v is not None}
        return options.replace(where=f"protocol {self.name!r}", **fixed) if fixed else options

    def as_dict(self) -> dict[str, Any]:
        return {k: list(v) if isinstance(v, tuple) else v
                for k, v in dataclasses.asdict(self).items()}


# SocialGym 2.0's five social mini-games (paper section VI), the scenarios its benchmark ran.
MINI_GAMES = ("open", "doorway", "hallway", "intersection", "roundabout")
# SocialGym 2.0's benchmark (paper section VI): the five mini-games at 3, 4, 5, 7 and 10 robots,
# 25 trials each, here with evaluation seed 0 and the counterfactual metrics. The one place these
# numbers are written: the evaluator's defaults, the command line's and the trainer's read them.
PAPER = Protocol(name="paper", scenarios=MINI_GAMES, num_agents=(3, 4, 5, 7, 10), episodes=25,
                 seed=0, counterfactual=True)
PROTOCOLS = {PAPER.name: PAPER}
_KEYS = [f.name for f in dataclasses.fields(Protocol)]
_REQUIRED = set(_KEYS) - {"time_limit", "num_humans", "human_range"}


def load_protocol(name_or_path: str | Path) -> Protocol:
    """A built-in protocol by name (:data:`PROTOCOLS`) or one read from a YAML file."""
    if str(name_or_path) in PROTOCOLS:
        return PROTOCOLS[str(name_or_path)]
    path = Path(name_or_path)
    if not path.is_file():
        raise FileNotFoundError(f"protocol {str(name_or_path)!r}: neither a built-in protocol "
                                f"({', '.join(PROTOCOLS)}) nor a file")
    try:
        data = yaml.safe_load(path.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as err:
        raise ValueError(f"{path}: not a YAML protocol file ({err})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: a protocol file is a mapping of {sorted(_KEYS)}")
    unknown, missing = set(data) - set(_KEYS), _REQUIRED - set(data)
    if unknown or missing:
        near = "".join(suggest(str(key), _KEYS) for key in sorted(unknown, key=str)[:1])
        raise ValueError(f"{path}: " + "; ".join(
            part for part in (f"unknown keys {sorted(unknown, key=str)}{near}" if unknown else "",
                              f"missing keys {sorted(missing)}" if missing else "") if part))
    values = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
    for key in ("time_limit", "human_range"):
        if isinstance(values.get(key), int) and not isinstance(values[key], bool):
            values[key] = float(values[key])
    try:
        return Protocol(**values)
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from None
