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

Every key is required except ``time_limit``; unknown keys are an error naming the file.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import yaml


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

    def __post_init__(self) -> None:
        where = f"protocol {self.name!r}"
        if not self.scenarios or not self.num_agents:
            raise ValueError(f"{where}: scenarios and num_agents must not be empty")
        if any(n < 1 for n in self.num_agents) or self.episodes < 1:
            raise ValueError(f"{where}: robot counts and episodes must be at least 1")
        if self.time_limit is not None and self.time_limit <= 0:
            raise ValueError(f"{where}: time_limit must be > 0 s, got {self.time_limit}")

    def make_kwargs(self) -> dict[str, Any]:
        """The ``sgjax.make`` settings the protocol fixes."""
        return {} if self.time_limit is None else {"time_limit": self.time_limit}

    def as_dict(self) -> dict[str, Any]:
        return {k: list(v) if isinstance(v, tuple) else v
                for k, v in dataclasses.asdict(self).items()}


# SocialGym 2.0's benchmark (paper section VI): the five mini-games at 3, 4, 5, 7 and 10 robots,
# 25 trials each, here with evaluation seed 0 and the counterfactual metrics.
PAPER = Protocol(name="paper", scenarios=("open", "doorway", "hallway", "intersection",
                                          "roundabout"),
                 num_agents=(3, 4, 5, 7, 10), episodes=25, seed=0, counterfactual=True)
PROTOCOLS = {PAPER.name: PAPER}
_KEYS = {f.name for f in dataclasses.fields(Protocol)}
_REQUIRED = _KEYS - {"time_limit"}


def load_protocol(name_or_path: str | Path) -> Protocol:
    """A built-in protocol by name (:data:`PROTOCOLS`) or one read from a YAML file."""
    if str(name_or_path) in PROTOCOLS:
        return PROTOCOLS[str(name_or_path)]
    path = Path(name_or_path)
    if not path.is_file():
        raise FileNotFoundError(f"protocol {str(name_or_path)!r}: neither a built-in protocol "
                                f"({', '.join(PROTOCOLS)}) nor a file")
    data = yaml.safe_load(path.read_text())
    if not isinstance(data, dict):
        raise ValueError(f"{path}: a protocol file is a mapping of {sorted(_KEYS)}")
    unknown, missing = set(data) - _KEYS, _REQUIRED - set(data)
    if unknown or missing:
        raise ValueError(f"{path}: " + "; ".join(
            part for part in (f"unknown keys {sorted(unknown)}" if unknown else "",
                              f"missing keys {sorted(missing)}" if missing else "") if part))
    try:
        return Protocol(
            name=str(data["name"]), scenarios=tuple(str(s) for s in data["scenarios"]),
            num_agents=tuple(int(n) for n in data["num_agents"]),
            episodes=int(data["episodes"]), seed=int(data["seed"]),
            counterfactual=_flag(data["counterfactual"], path),
            time_limit=None if data.get("time_limit") is None else float(data["time_limit"]))
    except (TypeError, ValueError) as err:
        raise ValueError(f"{path}: {err}") from err


def _flag(value: Any, path: Path) -> bool:
    if not isinstance(value, bool):
        raise ValueError(f"{path}: counterfactual must be true or false, got {value!r}")
    return value
