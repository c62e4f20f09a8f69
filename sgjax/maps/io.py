"""Loading maps by name or path, and the list of shipped maps."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

from sgjax.files import write_atomic
from sgjax.maps.crowd_scenarios import CROWD_SCENARIOS
from sgjax.maps.schema import DEFAULT_CLEARANCE, MapError, MapSpec, parse_map

_PACKAGE = "sgjax.shipped_maps"


def shipped_map_names() -> list[str]:
    """Names of the maps shipped with sgjax (the JSON files in ``maps/``)."""
    folder = resources.files(_PACKAGE)
    return sorted(p.name[: -len(".json")] for p in folder.iterdir() if p.name.endswith(".json"))


def save(spec: MapSpec, path: str | Path) -> Path:
    """Write a map to a JSON file in the sgjax format."""
    path = Path(path)
    write_atomic(path, json.dumps(spec.to_json(), indent=1) + "\n")
    return path


def load(name_or_path: str | Path, clearance: float = DEFAULT_CLEARANCE) -> MapSpec:
    """Load and validate a map: a shipped name (``"doorway"``), a generated crowd scenario
    (``"circle_crossing"``, :mod:`sgjax.maps.crowd_scenarios`), a path to a JSON file, or a
    SocialGym 2.0 map folder (imported by :func:`sgjax.maps.socialgym.import_socialgym`).

    ``clearance`` (m) is the largest robot radius the map must accommodate.
    Raises :class:`MapError` naming the file, the JSON path and the problem.
    """
    text_path = str(name_or_path)
    if Path(text_path).is_dir():  # a SocialGym 2.0 map folder, imported
        from sgjax.maps.socialgym import import_socialgym

        spec = import_socialgym(text_path)
        return spec if clearance == DEFAULT_CLEARANCE else parse_map(
            spec.to_json(), source=spec.source, clearance=clearance)
    if text_path.endswith(".json") or Path(text_path).exists():
        path = Path(text_path)
        if not path.exists():
            raise FileNotFoundError(f"map file not found: {path}")
        source, text = str(path), path.read_text()
    elif text_path in CROWD_SCENARIOS:  # generated, at its default settings
        spec = CROWD_SCENARIOS[text_path]()
        return spec if clearance == DEFAULT_CLEARANCE else parse_map(
            spec.to_json(), source=spec.source, clearance=clearance)
    else:
        names = shipped_map_names()
        if text_path not in names:
            raise KeyError(
                f"unknown map {text_path!r}; shipped maps are: {', '.join(names)} "
                "(or pass a path to a .json file)"
            )
        resource = resources.files(_PACKAGE) / f"{text_path}.json"
        source, text = f"maps/{text_path}.json", resource.read_text()
    try:
        data = json.loads(text)
    except json.JSONDecodeError as err:
        raise MapError(source, f"line {err.lineno} column {err.colno}",
                       f"invalid JSON: {err.msg}") from None
    return parse_map(data, source=source, clearance=clearance)
