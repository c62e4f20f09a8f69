"""Named observation, reward and ender sets, and loading term configurations from YAML/JSON.

Presets are plain specs in the same format a user writes (``docs/terms.md``), so every preset is
also an example. The SocialGym 2.0 presets follow its ``config_run.py`` defaults and shipped
configs (``socialgym2.md`` section 4): CADRL = its ``SACADRL`` run type, ``any_order`` /
``enforced_order`` = its ``AO`` / ``EO`` run types.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from sgjax.observations import Observer
from sgjax.rewards import Rewarder, RewardParams
from sgjax.terms.base import ConfigError, unknown_name
from sgjax.terms.enders import Enders

ZONE_OBSERVATIONS = ["zone_priority", "zone_order", "in_zone", "entering_zone", "exiting_zone",
                     "zone_entering_count", "zone_exiting_count"]

# SocialGym's observation set with every toggle its shipped configs turn on: goal distance with
# a 2-step history, the goal (world), own pose and body velocity (2-step history), the
# collision flag, and the others' poses and velocities (here the 6 nearest, robot frame).
_SOCIALGYM_OBSERVATIONS: list[Any] = [
    {"goal_distance": {"history": 2}},
    {"goal": {"frame": "world"}},
    {"pose": {"heading": True}},
    {"velocity": {"frame": "body", "history": 2}},
    "collision",
    {"others": {"k": 6, "features": ["position", "heading", "velocity", "mask"]}},
]

OBSERVATION_PRESETS: dict[str, list[Any]] = {
    # Own pose (x, y, cos, sin), body velocity (v_forward, v_lateral, omega), goal in the robot
    # frame and its distance: [R, 10].
    "default": ["pose", "velocity", {"goal": {"frame": "robot"}}, "goal_distance"],
    # Default plus the others and the next waypoint: what a learned policy usually wants.
    "navigation": ["pose", "velocity", {"goal": {"frame": "robot"}}, "goal_distance",
                   "waypoint", {"others": {"k": 4}}],
    # what a policy can carry between worlds: nothing in world coordinates, nothing sized by
    # the map (the zone ahead, not one block per zone)
    "transfer": [{"velocity": {"frame": "body"}}, {"goal": {"frame": "robot"}}, "goal_distance",
                 "waypoint", {"lidar": {"beams": 16, "range": 5.0}}, {"others": {"k": 4}},
                 "zone_ahead"],
    "socialgym": _SOCIALGYM_OBSERVATIONS,
    "cadrl": _SOCIALGYM_OBSERVATIONS,
    "any_order": _SOCIALGYM_OBSERVATIONS + ZONE_OBSERVATIONS,
    "enforced_order": _SOCIALGYM_OBSERVATIONS + ZONE_OBSERVATIONS,
}

# SocialGym's driver rewards: existence -1 per step, success +100, collision -10 per onset and
# the goal-distance change (weight 1); its configs end an episode on a 3000-step time limit or
# when stuck (the robots' path over 100 steps under the threshold), with -100000 to the robots
# that had not finished.
_SOCIALGYM_REWARDS: dict[str, Any] = {"existence": 1.0, "success": 100.0, "collision": 10.0,
                                      "progress": 1.0}
_SOCIALGYM_ENDERS: list[Any] = ["success", "time_limit",
                                {"stuck": {"distance": 0.5, "steps": 100, "penalty": -100000.0}}]
_ZONE_WEIGHT = 25.0  # SocialGym's enforced_order_reward

REWARD_PRESETS: dict[str, dict[str, Any]] = {
    # Metres gained toward the goal, +100 once on arrival, -10 per collision onset.
    "default": {"rewards": {"progress": 1.0, "success": 100.0, "collision": 10.0},
                "enders": ["success", "time_limit"]},
    "socialgym": {"rewards": _SOCIALGYM_REWARDS, "enders": _SOCIALGYM_ENDERS},
    # The paper's CADRL baseline: goal reward, collision and proximity penalties (CADRL's
    # -0.1 + d/2 under 0.2 m, scaled like the goal reward, x100) and the time (existence)
    # penalty, on SocialGym's SACADRL reward set.
    "cadrl": {"rewards": {**_SOCIALGYM_REWARDS, "proximity": {"weight": 100.0,
                                                              "threshold": 0.2}},
              "enders": _SOCIALGYM_ENDERS},
    "any_order": {"rewards": {**_SOCIALGYM_REWARDS, "zone_order": {
        "weight": _ZONE_WEIGHT, "any_order": True, "incorrect_penalty": False}},
        "enders": _SOCIALGYM_ENDERS},
    "enforced_order": {"rewards": {**_SOCIALGYM_REWARDS, "zone_order": {
        "weight": _ZONE_WEIGHT, "any_order": False, "incorrect_penalty": True}},
        "enders": _SOCIALGYM_ENDERS},
}

SECTIONS = ("observations", "rewards", "enders")


def load_terms_file(path: str | Path) -> dict[str, Any]:
    """Read a YAML or JSON file holding any of ``observations``, ``rewards``, ``enders``."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: no such file")
    text = path.read_text()
    if path.suffix == ".json":
        data = json.loads(text)
    else:
        try:
            import yaml
        except ImportError as err:  # pragma: no cover - PyYAML is a dependency
            raise ConfigError(f"{path}: reading YAML needs PyYAML (pip install pyyaml)") from err
        data = yaml.safe_load(text)
    if not isinstance(data, Mapping):
        raise ConfigError(f"{path}: expected a mapping with keys {list(SECTIONS)}, got "
                          f"{type(data).__name__}")
    unknown = [k for k in data if k not in SECTIONS]
    if unknown:
        raise unknown_name(str(path), "section", str(unknown[0]), list(SECTIONS))
    return dict(data)


def _preset(kind: str, name: str, presets: Mapping[str, Any]) -> Any:
    if name not in presets:
        raise unknown_name(f"{kind}_preset", "preset", name, list(presets))
    return copy.deepcopy(presets[name])


def resolve_terms(
    observations: Any = None, rewards: Any = None, enders: Any = None, terms: Any = None
) -> tuple[Observer, Rewarder, RewardParams, Enders]:
    """Build the Observer, Rewarder (with its weights) and Enders from ``make`` arguments.

    ``observations`` / ``rewards``: a preset name, a spec, or a path to a YAML/JSON file;
    ``enders``: a spec or a path; ``terms``: a mapping or file with any of the three sections.
    A reward preset brings its enders unless ``enders`` is given; the defaults are the
    ``default`` presets."""
    given = {"observations": observations, "rewards": rewards, "enders": enders}
    if terms is not None:
        bundle = load_terms_file(terms) if isinstance(terms, str | Path) else terms
        if not isinstance(bundle, Mapping):
            raise ConfigError(f"terms: expected a mapping with keys {list(SECTIONS)} or a file")
        for key, value in bundle.items():
            if key not in SECTIONS:
                raise unknown_name("terms", "section", str(key), list(SECTIONS))
            if given[key] is not None:
                raise ConfigError(f"{key} given twice: in terms and as {key}=")
            given[key] = value
    for key, value in list(given.items()):
        if isinstance(value, Path) or (isinstance(value, str) and (
                value.endswith((".yaml", ".yml", ".json")))):
            data = load_terms_file(value)
            if key not in data:
                raise ConfigError(f"{value}: no {key!r} section")
            given[key] = data[key]

    obs_spec = given["observations"] if given["observations"] is not None else "default"
    if isinstance(obs_spec, str):
        obs_spec = _preset("observation", obs_spec, OBSERVATION_PRESETS)
    reward_spec = given["rewards"] if given["rewards"] is not None else "default"
    ender_spec = given["enders"]
    if isinstance(reward_spec, str):
        preset = _preset("reward", reward_spec, REWARD_PRESETS)
        reward_spec = preset["rewards"]
        ender_spec = preset["enders"] if ender_spec is None else ender_spec
    if isinstance(ender_spec, str):
        ender_spec = _preset("reward", ender_spec, REWARD_PRESETS)["enders"]
    if ender_spec is None:
        ender_spec = REWARD_PRESETS["default"]["enders"]
    observer = Observer.parse(obs_spec)
    rewarder, reward_params = Rewarder.parse(reward_spec)
    return observer, rewarder, reward_params, Enders.parse(ender_spec)
