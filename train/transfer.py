"""Judge a transfer experiment: trained runs ("arms") on worlds they never trained on.

Every arm is a training run of several seeds (``python -m train --set num_seeds=5``: the
specialist of ``train/configs/transfer_doorway.yaml``, domain randomisation of
``transfer_dr.yaml``, a curriculum of ``transfer_curriculum.yaml``). Each held-out **set** is a
list of maps, each played at a fixed robot count; on every map every seed of every arm and
Only Local play the same episodes (the same evaluation key: common random numbers), so their
differences pair episode by episode::

    python -m train.transfer --arm specialist=runs/transfer_doorway \\
        --arm dr=runs/transfer_dr --arm curriculum=runs/transfer_curriculum \\
        --reference specialist --own-specialist specialist \\
        --own-specialist runs/transfer_hallway --episodes 100 --out docs/results/transfer

Sets (``--sets``, all by default):

* ``minigames``: the five shipped mini-games (``doorway`` ... ``open``);
* ``office``: the shipped office floor;
* ``sg2maps``: SocialGym 2.0's real map folders (``--sg2maps``, default ``../shared/sg2maps``),
  imported as ``sgjax.maps.import_socialgym`` does; a map with no room for ``--robots`` robots
  is played at the most it places (the table says so);
* ``generated_test`` / ``generated_train``: each generated family's held-out test split
  (world seeds ``TEST_SEEDS``, never drawn by a run made with ``world_holdout``) and its train
  split (seeds ``0 ..``), under the families' default ranges: their difference is the
  generalisation gap;
* ``extrapolation``: parameters beyond the training ranges (narrower doors, longer and
  narrower hallways, smaller roundabouts, more robots than training met);
* ``recorded`` (asked for by name; issue 68's sim-to-real gap): the five standard ETH/UCY
  scenes (``--recordings``, default ``../shared/pedestrians/eth_ucy``) as ``recorded:FILE``
  scenarios, the robots among the recorded people themselves, once as ghosts and once handed
  over within 1.5 m to the Moussaid law with the constants fitted to those people
  (``human_constants="eth_ucy"``: the same for every arm, whatever crowd it trained among);
  beside team success it keeps collisions with people, personal-space intrusions, the log
  deviation and the people reached;
* ``simulated_crowds`` (asked for by name, beside ``recorded``): the same five scenes with
  simulated people instead (12, the Moussaid law, the published constants and the fitted
  ones: the crowds the gap's arms trained among), so that what a simulated crowd predicts
  about the recorded people is measured on the same scenes, robots and episodes.

Whether a family or map was seen in training is read from each arm's config and marked. A
shipped map's **own specialist** (``--own-specialist``: an arm's name, or a run trained on that
map alone, played there only) is compared with every arm on its map.

Outputs in ``--out``: ``transfer.json`` (schema ``sgjax.transfer/1``: every seed's team success
per episode, every seed's mean collisions and makespan per map, Only Local's per episode, with
provenance) and ``transfer.md`` (generated from it; ``--from-results`` writes it again):

* every map's team success per arm (mean over seeds with a percentile-bootstrap interval over
  seeds) beside Only Local's;
* each arm against Only Local and each other arm against ``--reference``, paired over seeds
  and episodes (:func:`sgjax.evaluation.statistics.paired_over_seeds_and_episodes`: seeds and
  episodes resampled together, the two arms' seeds paired by index);
* per set, the maps where each arm beats Only Local (its paired interval above 0) and where it
  is within ``--margin`` of the reference (the interval's low end above ``-margin``).

Both files are written again after every map (``pending`` lists the maps still to play), so
a run killed midway continues with ``--resume`` from ``transfer.json``. It also lets arms
arrive one by one: a later ``--resume`` with an arm added (or retrained) plays that arm alone
on every map and keeps the others' values and Only Local's, on the same episodes.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import hashlib
import json
import math
import time
import zlib
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import jax
import numpy as np

from sgjax.compilation_cache import add_cache_arguments, cache_from_arguments
from sgjax.environment.options import MakeOptions
from sgjax.evaluation.policies import load_policy
from sgjax.evaluation.provenance import provenance, run_git_state
from sgjax.evaluation.report import markdown_table
from sgjax.evaluation.runner import EpisodeRunner
from sgjax.evaluation.statistics import (
    aggregate_over_cells,
    improvement_over_cells,
    paired_over_seeds_and_episodes,
    seed_aggregate,
)
from sgjax.evaluation.trained import TrainedEvaluation
from sgjax.files import write_atomic
from sgjax.maps.generated.families import PREFIX
from sgjax.maps.generated.splits import TEST_SEEDS
from train.algorithm.actor import ActorWeights, TrainedActor
from train.reports.result_schemas import TRANSFER
from train.run import checkpoint
from train.run.worst_worlds import WorstPlayers, worst_of_seeds

ROOT = Path(__file__).resolve().parents[1]
SG2MAPS = ROOT.parent / "shared" / "sg2maps"
MINIGAMES = ("doorway", "hallway", "intersection", "roundabout", "open")
FAMILIES = ("doorway", "hallway", "intersection", "roundabout", "open", "floorplan")
SETS = ("minigames", "office", "sg2maps", "generated_test", "generated_train", "extrapolation",
        "recorded", "simulated_crowds")
DEFAULT_SETS = SETS[:-2]  # the recorded scenes are asked for by name
RECORDINGS = ROOT.parent / "shared" / "pedestrians" / "eth_ucy"
RECORDED_SCENES = {"ETH": "biwi_eth", "HOTEL": "biwi_hotel", "UNIV": "students001",
                   "ZARA1": "crowds_zara01", "ZARA2": "crowds_zara02"}
RECORDED_BEHAVIOURS = ("ghost", "handover")
# among recorded people, beside METRICS: what the robots did to the people
RECORDED_METRICS = ("collisions_human", "personal_space_human", "log_deviation",
                    "people_reached")
# The same scenes with simulated people (the crowd the gap's arms trained among,
# train/configs/crowd_gap_*.yaml): the Moussaid law with each set of constants, so that what
# the simulated crowds predict is measured beside the recorded people.
SIMULATED_PEOPLE = 12
SIMULATED_CONSTANTS = (("published constants", "published"), ("fitted constants", "eth_ucy"))
SIMULATED_METRICS = ("collisions_human", "personal_space_human")  # no recording to deviate from
SPLIT_WORLDS = 1000  # worlds in a generated split (its episodes draw among them)
EXTRA_ROBOTS = 7  # "more robots than in training" (the transfer configs train with 3 to 5)
# Parameter extrapolation: (name, family, ranges beyond the training defaults).
EXTRAPOLATION: tuple[tuple[str, str, dict[str, tuple[float, float]]], ...] = (
    ("doorway, narrow doors", "doorway", {"door_width": (0.7, 0.9)}),
    ("doorway, thick walls", "doorway", {"wall_thickness": (1.5, 2.0)}),
    ("hallway, long", "hallway", {"corridor_length": (10.0, 14.0)}),
    ("hallway, narrow", "hallway", {"corridor_width": (0.7, 0.9)}),
    ("roundabout, narrow ring", "roundabout", {"arm_width": (2.6, 3.5)}),
    ("open, large arena", "open", {"arena_size": (16.0, 20.0)}),
)
METRICS = ("team_success", "collisions", "makespan")
OWN = "own specialist"  # a map's own specialist in comparisons' names
RESAMPLES = 4000


@dataclasses.dataclass(frozen=True)
class HeldOutMap:
    """One map of a held-out set: ``scenario`` (a shipped or generated name, or a SocialGym
    2.0 map folder), played at ``robots`` robots in ``worlds`` (``sgjax.make``'s world
    keywords: a split's seeds, extrapolated ranges)."""

    set: str
    name: str
    scenario: str
    robots: int
    worlds: tuple[tuple[str, Any], ...] = ()
    socialgym_folder: bool = False
    keywords: tuple[tuple[str, Any], ...] = ()  # other make keywords the map sets for every arm
    metrics: tuple[str, ...] = METRICS  # what is kept per episode

    @property
    def key(self) -> str:
        return f"{self.set}/{self.name}"


def recorded_scenes(recordings: Path = RECORDINGS) -> dict[str, Path]:
    """Each standard ETH/UCY scene's track file in ``recordings``; a missing file is named."""
    paths = {}
    for scene, stem in RECORDED_SCENES.items():
        paths[scene] = recordings / f"{stem}.txt"
        if not paths[scene].is_file():
            raise ValueError(f"--recordings: no {stem}.txt in {recordings} (the ETH/UCY "
                             "track files, ../shared/pedestrians/eth_ucy); leave the recorded "
                             "sets out or give the folder")
    return paths


def simulated_crowd_maps(robots: int, recordings: Path = RECORDINGS) -> list[HeldOutMap]:
    """The ``simulated_crowds`` set: each standard ETH/UCY scene as the gap's arms trained in
    it, its open space with :data:`SIMULATED_PEOPLE` simulated people (the Moussaid law, no
    replay), once with the published constants and once with those fitted to ETH/UCY (the
    same for every arm), keeping collisions with people and personal-space intrusions."""
    return [HeldOutMap("simulated_crowds", f"{scene}, {label}", f"recorded:{path}", robots,
                       keywords=(("human_replay", "off"), ("num_humans", SIMULATED_PEOPLE),
                                 ("max_humans", None), ("human_model", "moussaid"),
                                 ("human_constants", constants)),
                       metrics=METRICS + SIMULATED_METRICS)
            for scene, path in recorded_scenes(recordings).items()
            for label, constants in SIMULATED_CONSTANTS]


def recorded_maps(robots: int, recordings: Path = RECORDINGS) -> list[HeldOutMap]:
    """The ``recorded`` set: each standard ETH/UCY scene of ``recordings`` with its people as
    ghosts and handed over (the module doc); a missing file is named."""
    maps = []
    for scene, path in recorded_scenes(recordings).items():
        for behaviour in RECORDED_BEHAVIOURS:
            maps.append(HeldOutMap(
                "recorded", f"{scene}, {behaviour}", f"recorded:{path}", robots,
                keywords=(("human_replay", behaviour), ("num_humans", 0),
                          ("max_humans", None), ("human_constants", "eth_ucy")),
                metrics=METRICS + RECORDED_METRICS))
    return maps


def held_out_maps(sets: Sequence[str], robots: int, sg2maps: Path = SG2MAPS,
                  recordings: Path = RECORDINGS) -> list[HeldOutMap]:
    """Every map of ``sets`` (names of :data:`SETS`), in order."""
    unknown = [s for s in sets if s not in SETS]
    if unknown:
        raise ValueError(f"--sets: unknown set(s) {unknown}; choose from {', '.join(SETS)}")
    maps: list[HeldOutMap] = []
    for name in sets:
        if name == "minigames":
            maps += [HeldOutMap(name, game, game, robots) for game in MINIGAMES]
        elif name == "office":
            maps.append(HeldOutMap(name, "office", "office", robots))
        elif name == "sg2maps":
            if not sg2maps.is_dir():
                raise ValueError(f"--sg2maps: {sg2maps} is not a folder (SocialGym 2.0's map "
                                 "folders, ../shared/sg2maps); leave the sg2maps set out or "
                                 "give its path")
            maps += [HeldOutMap(name, folder.name, str(folder), robots, socialgym_folder=True)
                     for folder in sorted(sg2maps.iterdir()) if folder.is_dir()]
        elif name == "recorded":
            maps += recorded_maps(robots, recordings)
        elif name == "simulated_crowds":
            maps += simulated_crowd_maps(robots, recordings)
        elif name in ("generated_test", "generated_train"):
            first = TEST_SEEDS[0] if name == "generated_test" else 0
            maps += [HeldOutMap(name, family, PREFIX + family, robots,
                                (("world_seeds", (first, SPLIT_WORLDS)),))
                     for family in FAMILIES]
        else:
            maps += [HeldOutMap(name, label, PREFIX + family, robots,
                                (("world_ranges", ranges),
                                 ("world_seeds", (TEST_SEEDS[0], SPLIT_WORLDS))))
                     for label, family, ranges in EXTRAPOLATION]
            maps.append(HeldOutMap(name, f"doorway, {EXTRA_ROBOTS} robots", PREFIX + "doorway",
                                   EXTRA_ROBOTS,
                                   (("world_seeds", (TEST_SEEDS[0], SPLIT_WORLDS)),)))
    return maps


@dataclasses.dataclass(frozen=True)
class Arm:
    """A trained run: its checkpoint, seed-batched acting weights ``[S, ...]``, actor spec,
    training options, play mode and the scenarios it trained on."""

    name: str
    path: Path
    actor: TrainedActor
    weights: ActorWeights
    options: MakeOptions
    deterministic: bool
    trained_on: tuple[str, ...]
    sha256: str

    @property
    def seeds(self) -> int:
        return self.weights.lanes


def load_arm(name: str, spec: str | Path) -> Arm:
    """The arm ``name`` from a run folder (its ``checkpoints/latest.msgpack``: the final
    weights, not a checkpoint picked on training worlds) or a checkpoint file."""
    path = Path(spec)
    if path.is_dir():
        path = path / "checkpoints" / "latest.msgpack"
    if not path.is_file():
        raise ValueError(f"--arm {name}={spec}: no checkpoint at {path}")
    config, meta, raw = checkpoint.read(path)
    layout = checkpoint.actor_layout(path, config, meta, raw)
    return Arm(name=name, path=path, actor=TrainedActor(config.network, layout),
               weights=checkpoint.stored_weights(raw), options=config.env.options,
               deterministic=bool(config.evaluation.deterministic),
               trained_on=tuple(config.env.scenarios),
               sha256=hashlib.sha256(path.read_bytes()).hexdigest())


def map_options(arm: Arm, held: HeldOutMap) -> MakeOptions:
    """``arm``'s training options on ``held``: its worlds keywords in place of the arm's
    (training's ranges, holdout and levels do not carry over), exactly ``held.robots``
    robots."""
    options = dataclasses.replace(arm.options, worlds=type(arm.options.worlds)())
    return options.replace(**dict(held.worlds), **dict(held.keywords), num_agents=held.robots,
                           min_agents=None, max_agents=None)


def _shared_part(options: MakeOptions) -> dict[str, Any]:
    """What decides the episodes on a held-out map: the options but the observation and
    reward terms and the worlds (training's ranges, held-out split and levels, which
    :func:`map_options` replaces)."""
    data = options.to_dict()
    data.pop("terms")
    data.pop("worlds")
    return data


def check_same_episodes(arms: Sequence[Arm], maps: Sequence[HeldOutMap] = ()) -> None:
    """Arms whose options differ in anything but their terms would play different episodes on
    the same key: refused, naming the arms and the keywords. With ``maps``, the options each
    map plays them with (:func:`map_options`: a map's keywords may set what the arms' training
    differed in, as the recorded set sets the pedestrians' constants)."""
    if maps:
        for held in maps:
            check_options_alike(arms, [map_options(arm, held) for arm in arms], held.key)
        return
    check_options_alike(arms, [arm.options for arm in arms])


def check_options_alike(arms: Sequence[Arm], options: Sequence[MakeOptions], where: str = ""
                        ) -> None:
    """:func:`check_same_episodes` of the ``options`` each arm plays with."""
    first = _shared_part(options[0])
    for arm, theirs in zip(arms[1:], options[1:], strict=True):
        other = _shared_part(theirs)
        differ = sorted(f"{section}.{key}" for section in first for key in first[section]
                        if first[section][key] != other[section][key])
        if differ:
            raise ValueError(f"arms {arms[0].name!r} and {arm.name!r} were trained with "
                             f"different make options ({', '.join(differ)}): they would not "
                             "play the same episodes"
                             + (f" on {where}" if where else "") + "; judge them separately")


def map_key(seed: int, held: HeldOutMap) -> jax.Array:
    """The evaluation key of a map: ``seed`` folded with a hash of the map's key, so a map's
    episodes do not depend on which other maps are judged."""
    return jax.random.fold_in(jax.random.PRNGKey(seed), zlib.crc32(held.key.encode()))


def scenario_of(held: HeldOutMap) -> Any:
    """What ``sgjax.make`` takes for the map (a SocialGym 2.0 folder is imported)."""
    if not held.socialgym_folder:
        return held.scenario
    from sgjax.maps.socialgym import import_socialgym

    return import_socialgym(held.scenario)


def fitted_robots(held: HeldOutMap, arm: Arm, scenario: Any) -> int:
    """``held.robots``, or fewer where the map has no room for them (a SocialGym 2.0 map
    whose starts and goals place fewer robots apart): the most it places, down to 1."""
    from sgjax import make

    for count in range(held.robots, 0, -1):
        try:
            make(scenario, options=map_options(arm, dataclasses.replace(held, robots=count)))
            return count
        except ValueError as err:
            if "cannot place" not in str(err) or not held.socialgym_folder:
                raise
    raise ValueError(f"{held.scenario}: places no robot")


def judge_map(arms: Sequence[Arm], held: HeldOutMap, episodes: int, seed: int,
              earlier: Mapping[str, Any] | None = None, own: Arm | None = None
              ) -> dict[str, Any]:
    """Every arm's seeds and Only Local on ``episodes`` shared episodes of ``held``:
    ``{"robots", "only_local": {metric: [E]}, "arms": {name: {metric: [S, E]}},
    "checkpoints": {name: sha256}}``, and ``"own_specialist"``: the name of the map's own
    specialist (``own``, a run trained on this map alone: one of ``arms`` or played here
    beside them, its values under ``arms`` too). An ``earlier`` result of the map (same
    episodes) lends Only Local's values and those of every arm whose checkpoint is
    unchanged, so an arm that finishes training later is judged alone."""
    earlier = earlier or {}
    if own is not None and own.name not in {arm.name for arm in arms}:
        arms = [*arms, own]
    scenario = scenario_of(held)
    robots = earlier.get("robots") or fitted_robots(held, arms[0], scenario)
    held = dataclasses.replace(held, robots=robots)
    key = map_key(seed, held)
    kept = {arm.name for arm in arms
            if earlier.get("checkpoints", {}).get(arm.name) == arm.sha256}
    out: dict[str, Any] = {"robots": robots,
                           "arms": {n: earlier["arms"][n] for n in sorted(kept)},
                           "checkpoints": {a.name: a.sha256 for a in arms}}
    if "only_local" in earlier:
        out["only_local"] = earlier["only_local"]
    draws = None
    for arm in arms:
        if arm.name in kept and "only_local" in out:
            continue
        evaluation = TrainedEvaluation(arm.actor, scenario, [robots], episodes,
                                       map_options(arm, held), modes=arm.deterministic)
        # terms may split a reset's key otherwise (zones, noisy observations): other episodes
        uses = (evaluation.env.config.uses_zones, evaluation.env.config.observer.needs_key)
        if draws is not None and uses != draws[1]:
            raise ValueError(f"{held.key}: arms {draws[0]!r} and {arm.name!r} draw their "
                             "episodes differently (one's terms use conflict zones or a "
                             "noisy observation, the other's not); judge them separately")
        draws = draws or (arm.name, uses)
        if arm.name not in kept:
            values, _ = jax.device_get(evaluation.lanes(arm.weights, key, robots))
            out["arms"][arm.name] = {m: _stored(values[m]) for m in held.metrics}
        if "only_local" not in out:
            runner = EpisodeRunner(evaluation.env, load_policy("only_local", evaluation.env),
                                   episodes, evaluation.num_steps)
            alone, _ = jax.device_get(runner.run(key, evaluation.params[robots])[:2])
            out["only_local"] = {m: _stored(alone[m]) for m in held.metrics}
    out["arms"] = {arm.name: out["arms"][arm.name] for arm in arms}
    if own is not None:
        out["own_specialist"] = own.name
    return out


def _stored(values: Any) -> list:
    """Per-episode values as the file keeps them: float32 values rounded to 4 decimals (their
    precision), NaN as JSON's NaN."""
    return np.round(np.asarray(values, np.float64), 4).tolist()


def settings(arms: Sequence[Arm], episodes: int, seed: int, robots: int) -> dict[str, Any]:
    """The settings that decide a map's episodes, which a resumed run must share with the file
    it continues: the arms' shared make options (:func:`_shared_part`), episodes, evaluation
    seed and robots. The arms themselves may change: each is judged again only where its
    checkpoint did."""
    return {"options": _shared_part(arms[0].options), "episodes": int(episodes),
            "seed": int(seed), "robots": int(robots)}


def own_specialists(chosen: Sequence[Arm], maps: Sequence[HeldOutMap]) -> dict[str, Arm]:
    """Each shipped map's own specialist, by map key: the ``chosen`` run (an arm or a run
    played beside the arms) trained on that map's scenario alone (maps of the ``minigames``
    and ``office`` sets). A run trained on anything else, or two runs for one map, are
    refused."""
    shipped: dict[str, list[str]] = {}
    for held in maps:
        if held.set in ("minigames", "office"):
            shipped.setdefault(held.scenario, []).append(held.key)
    own: dict[str, Arm] = {}
    for arm in chosen:
        alone = arm.trained_on[0] if len(arm.trained_on) == 1 else None
        if alone not in shipped:
            raise ValueError(f"--own-specialist {arm.name}: trained on "
                             f"{', '.join(arm.trained_on)}, not on one shipped map of the "
                             "judged sets (minigames, office) alone")
        for key in shipped[alone]:
            if key in own:
                raise ValueError(f"--own-specialist: {own[key].name!r} and {arm.name!r} both "
                                 f"trained on {alone} alone; give one per map")
            own[key] = arm
    return own


def is_complete(result: Mapping[str, Any] | None, arms: Sequence[Arm], own: Arm | None
                ) -> bool:
    """Whether a map's ``result`` holds every arm's current checkpoint, its own specialist's
    and names that specialist (nothing left to play there)."""
    wanted = {**{a.name: a.sha256 for a in arms},
              **({own.name: own.sha256} if own is not None else {})}
    return (result is not None and result.get("checkpoints") == wanted
            and result.get("own_specialist") == (own.name if own else None))


def judge(arms: Sequence[Arm], maps: Sequence[HeldOutMap], episodes: int, seed: int,
          done: dict[str, Any] | None = None, on_map: Callable[[str, dict], None] | None = None,
          log: Callable[[str], None] = print, own: Mapping[str, Arm] | None = None
          ) -> dict[str, Any]:
    """:func:`judge_map` of every map whose result in ``done`` (``{map key: result}``) lacks
    an arm or holds an arm's older checkpoint; ``on_map(key, result)`` after each. ``own``
    gives maps their own specialists (:func:`own_specialists`). Returns every map's result
    by key."""
    own = dict(own or {})
    names = {a.name for a in arms}
    check_same_episodes([*arms, *(a for a in own.values() if a.name not in names)], maps)
    results = dict(done or {})
    for number, held in enumerate(maps, 1):
        earlier = results.get(held.key)
        if is_complete(earlier, arms, own.get(held.key)):
            continue
        result = {"set": held.set, "name": held.name, "scenario": held.scenario,
                  "worlds": {k: v for k, v in held.worlds},
                  **({"keywords": dict(held.keywords)} if held.keywords else {}),
                  **judge_map(arms, held, episodes, seed, earlier, own.get(held.key))}
        results[held.key] = result
        if on_map is not None:
            on_map(held.key, result)
        log(f"[{number}/{len(maps)}] {held.key} ({result['robots']} robots): "
            + ", ".join(f"{name} {_mean(v['team_success']):.2f}"
                        for name, v in result["arms"].items())
            + f", only_local {_mean(result['only_local']['team_success']):.2f}")
    return results


WORST_PROTOCOL = "sfl"  # rollout B plays only the worst max-alpha worlds (play_worst)


def judge_worst(arms: Sequence[Arm], robots: int, worlds: int, alphas: Sequence[float],
                seed: int, earlier: Mapping[str, Any] | None = None,
                log: Callable[[str], None] = print,
                on_family: Callable[[dict[str, Any]], None] | None = None) -> dict[str, Any]:
    """Every arm's worst-alpha team success per generated family over ``worlds`` held-out
    worlds (:func:`train.run.worst_worlds.worst_of_seeds`): ``{"worlds", "alphas",
    "protocol", "provenance", "arms": {name: {"sha256", "families": {family: {alpha: [S]}}}},
    "pending": ["arm/family", ...]}``, played family by family (every arm of a family on one
    compiled player, :class:`train.run.worst_worlds.WorstPlayers`, where the arms' actor spec,
    options and play mode agree). ``on_family(block)`` after every family an arm played
    (the block so far, its ``pending`` the pairs still to play), so that a stopped run keeps
    what it finished. An ``earlier`` block of the same worlds, alphas and protocol, made by
    the same code (its provenance's git state), lends every family an unchanged checkpoint
    played there."""
    keys = [f"{a:g}" for a in alphas]
    git = run_git_state()
    same = (earlier is not None and earlier.get("worlds") == worlds
            and earlier.get("alphas") == keys and earlier.get("protocol") == WORST_PROTOCOL
            and earlier.get("provenance", {}).get("git") == git)
    if earlier is not None and not same:
        log("worst worlds: the earlier result differs in worlds, alphas, protocol or code; "
            "playing every arm again")
    start = time.perf_counter()
    spent = float(earlier.get("provenance", {}).get("seconds", {}).get("worst", 0.0)
                  if same else 0.0)
    out: dict[str, Any] = {"worlds": int(worlds), "alphas": keys, "protocol": WORST_PROTOCOL,
                           "arms": {}}
    pairs = [(arm.name, family) for family in FAMILIES for arm in arms]  # the play order

    def block() -> dict[str, Any]:
        out["provenance"] = provenance(
            {"worlds": int(worlds), "alphas": keys, "robots": robots, "seed": seed,
             "protocol": WORST_PROTOCOL, "arms": {a.name: a.sha256 for a in arms}},
            seeds={"evaluation": [seed]},
            seconds={"worst": spent + time.perf_counter() - start})
        out["pending"] = [f"{n}/{f}" for n, f in pairs
                          if f not in out["arms"].get(n, {}).get("families", {})]
        return out

    for arm in arms:  # what an earlier run of the same code played for an unchanged arm
        old = (earlier or {}).get("arms", {}).get(arm.name, {}) if same else {}
        kept = old.get("families", {}) if old.get("sha256") == arm.sha256 else {}
        out["arms"][arm.name] = {"sha256": arm.sha256, "families": {
            f: kept[f] for f in FAMILIES if f in kept}}
    players = WorstPlayers()  # every arm of a family on one compiled player where they can
    for family in FAMILIES:  # family by family, so that the arms share its player
        held = HeldOutMap("generated_test", family, PREFIX + family, robots)
        for arm in arms:
            families = out["arms"][arm.name]["families"]
            if family in families:
                continue
            families[family] = worst_of_seeds(arm.actor, arm.weights, arm.deterministic,
                                              map_options(arm, held), family, robots, worlds,
                                              alphas, seed, players=players)
            log(f"worst of {worlds} {family} worlds, {arm.name}: " + ", ".join(
                f"{k}: {_mean(v):.2f}" for k, v in families[family].items()))
            if on_family is not None:
                on_family(block())
    for arm in arms:  # each arm's families in FAMILIES order, whichever order they were played
        families = out["arms"][arm.name]["families"]
        out["arms"][arm.name]["families"] = {f: families[f] for f in FAMILIES if f in families}
    return block()


def worst_section(worst: Mapping[str, Any]) -> list[str]:
    """The worst-case table: per family, each arm's worst-alpha team success (mean over seeds
    [95% percentile-bootstrap interval over seeds]) for every alpha; a family some arm has
    played is listed, "pending" where another has not yet."""
    arms = worst["arms"]
    header = ["family", *(f"{name} worst {100 * float(a):g}%" for name in arms
                          for a in worst["alphas"])]
    def cell(name: str, family: str, alpha: str) -> str:
        played = arms[name]["families"].get(family)
        return "pending" if played is None else _seed_cell([[v] for v in played[alpha]])

    rows = [[family, *(cell(name, family, a) for name in arms for a in worst["alphas"])]
            for family in FAMILIES if any(family in arms[n]["families"] for n in arms)]
    return [f"## Worst case over {worst['worlds']:,} held-out worlds per family", "",
            "Each seed plays every world of the family's test split once (rollout key A) "
            "and the worst worlds again (rollout key B); its score is rollout B's team "
            "success on the alpha share rollout A scored lowest (SFL's worst alpha%: ranking "
            "and scoring on one rollout would pick worlds for their bad luck). Mean over "
            "seeds [95% percentile-bootstrap interval over seeds].",
            "", *markdown_table(header, rows), ""]


def _mean(values: Any) -> float:
    x = np.asarray(values, float)
    return float(np.nanmean(x)) if np.isfinite(x).any() else math.nan


def seen_in_training(arm: Mapping[str, Any], result: Mapping[str, Any]) -> bool:
    """Whether ``arm`` (its record in the result file) trained on the map's scenario (a
    generated family counts as seen on its train split and held-out ones alike: the worlds
    differ, the family does not)."""
    return result["scenario"] in arm["trained_on"]


def comparisons(result: Mapping[str, Any], reference: str | None) -> dict[str, dict]:
    """Paired team-success differences on one map: ``"<arm> - only_local"`` for every arm,
    ``"<arm> - <reference>"`` for every other arm and, on a map with its own specialist,
    ``"<arm> - own specialist"`` for every arm but that one (``Summary.as_dict``)."""
    out = {}
    arms = result["arms"]
    base = np.asarray(result["only_local"]["team_success"], float)
    for name, values in arms.items():
        a = np.asarray(values["team_success"], float)
        out[f"{name} - only_local"] = paired_over_seeds_and_episodes(
            a, base, resamples=RESAMPLES).as_dict()
        if reference is not None and name != reference:
            b = np.asarray(arms[reference]["team_success"], float)
            if a.shape != b.shape:  # seeds pair by index: unequal counts do not pair
                raise ValueError(f"{name} ({a.shape[0]} seeds) and the reference {reference} "
                                 f"({b.shape[0]} seeds): a paired comparison needs as many "
                                 "seeds in each")
            out[f"{name} - {reference}"] = paired_over_seeds_and_episodes(
                a, b, resamples=RESAMPLES).as_dict()
    extra = [m for m in result["only_local"] if m not in METRICS]  # the recorded set's
    for name, values in arms.items():
        for metric in extra:
            a = np.asarray(values[metric], float)
            out[f"{name} - only_local: {metric}"] = paired_over_seeds_and_episodes(
                a, np.asarray(result["only_local"][metric], float),
                resamples=RESAMPLES).as_dict()
            if reference is not None and name != reference:
                out[f"{name} - {reference}: {metric}"] = paired_over_seeds_and_episodes(
                    a, np.asarray(arms[reference][metric], float),
                    resamples=RESAMPLES).as_dict()
    own = result.get("own_specialist")
    for name in arms if own is not None else ():
        if name != own:
            out[f"{name} - {OWN}"] = paired_over_seeds_and_episodes(
                np.asarray(arms[name]["team_success"], float),
                np.asarray(arms[own]["team_success"], float), resamples=RESAMPLES).as_dict()
    return out


def _points(summary: Mapping[str, Any]) -> str:
    """A paired difference in percentage points: ``+12 [+4, +20]``."""
    if summary["mean"] is None:
        return "n/a"
    return (f"{100 * summary['mean']:+.0f} [{100 * summary['ci_low']:+.0f}, "
            f"{100 * summary['ci_high']:+.0f}]")


def _seed_means(values: Any) -> np.ndarray:
    """Each seed's mean over its episodes (``values [S, E]``, NaN-aware): ``[S]``."""
    return np.array([_mean(row) for row in values], float)


def _seed_cell(values: Any) -> str:
    """Team success over seeds: each seed's mean over the episodes, their mean [95%
    percentile-bootstrap interval over seeds]."""
    agg = seed_aggregate(_seed_means(values))
    if math.isnan(agg["mean"]):
        return "n/a"
    if math.isnan(agg["mean_low"]):
        return f"{agg['mean']:.2f}"
    return f"{agg['mean']:.2f} [{agg['mean_low']:.2f}, {agg['mean_high']:.2f}]"


def _per_seed_mean(values: Any) -> str:
    mean = _mean(_seed_means(values))
    return "n/a" if math.isnan(mean) else f"{mean:.2f}"


def map_label(result: Mapping[str, Any], arms: Mapping[str, Any], robots: int) -> str:
    """The map's name, with its robot count where it differs from the set's and a mark for
    each arm that trained on its scenario."""
    label = result["name"]
    if result["robots"] != robots:
        label += f" ({result['robots']} robots)"
    seen = [name for name, arm in arms.items() if seen_in_training(arm, result)]
    return label + (f" · trained on by {', '.join(seen)}" if seen else "")


def _team(result: Mapping[str, Any], arm: str) -> float:
    """``arm``'s team success on a map, over all its seeds and episodes."""
    return _mean(result["arms"][arm]["team_success"])


def set_section(name: str, results: Sequence[Mapping[str, Any]], document: Mapping[str, Any]
                ) -> list[str]:
    """A set's two tables: team success with the paired differences, then collisions and
    makespan."""
    arms, reference, robots = document["arms"], document["reference"], document["robots"]
    names = list(arms)
    others = [n for n in names if reference is not None and n != reference]
    with_own = any("own_specialist" in r for r in results)
    rows = [[map_label(r, arms, robots), f"{_mean(r['only_local']['team_success']):.2f}",
             *(_seed_cell(r["arms"][n]["team_success"]) for n in names),
             *(_points(r["paired"][f"{n} - only_local"]) for n in names),
             *(_points(r["paired"][f"{n} - {reference}"]) for n in others),
             *(_own_cells(r, names) if with_own else ())] for r in results]
    costs = [[r["name"], *(_per_seed_mean(r["arms"][n]["collisions"]) for n in names),
              *(_per_seed_mean(r["arms"][n]["makespan"]) for n in names)] for r in results]
    return [f"## {name}", "",
            *markdown_table(["map", "Only Local", *names,
                             *(f"{n} - Only Local" for n in names),
                             *(f"{n} - {reference}" for n in others),
                             *((OWN, *(f"{n} - {OWN}" for n in names)) if with_own else ())],
                            rows), "",
            "Collisions per episode and makespan (s), mean over seeds:", "",
            *markdown_table(["map", *(f"{n} collisions" for n in names),
                             *(f"{n} makespan" for n in names)], costs), "",
            *people_section(results, names, others, reference)]


PEOPLE_LABELS = {"collisions_human": "collisions with people per episode",
                 "personal_space_human": "personal-space intrusions (s per episode)",
                 "log_deviation": "log deviation (m)", "people_reached": "people reached"}


def people_section(results: Sequence[Mapping[str, Any]], names: Sequence[str],
                   others: Sequence[str], reference: str | None) -> list[str]:
    """Among recorded people: per metric of :data:`RECORDED_METRICS` the maps' values of Only
    Local and of every arm (mean over seeds [95% percentile-bootstrap interval over seeds]),
    with each other arm's paired difference from the reference; nothing for maps without
    them."""
    lines: list[str] = []
    for metric in RECORDED_METRICS:
        held = [r for r in results if metric in r["only_local"]]
        if not held:
            continue
        rows = [[r["name"], f"{_mean(r['only_local'][metric]):.2f}",
                 *(_seed_cell(r["arms"][n][metric]) for n in names),
                 *(_value_diff(r["paired"][f"{n} - {reference}: {metric}"]) for n in others)]
                for r in held]
        lines += [f"{PEOPLE_LABELS[metric].capitalize()}:", "",
                  *markdown_table(["map", "Only Local", *names,
                                   *(f"{n} - {reference}" for n in others)], rows), ""]
    return lines


def _value_diff(summary: Mapping[str, Any]) -> str:
    """A paired difference in the metric's own units: ``+0.12 [+0.04, +0.20]``."""
    if summary["mean"] is None:
        return "n/a"
    return f"{summary['mean']:+.2f} [{summary['ci_low']:+.2f}, {summary['ci_high']:+.2f}]"


def _own_cells(result: Mapping[str, Any], names: Sequence[str]) -> list[str]:
    """A map's own specialist (its team success, or the arm's name where it is one of the
    arms) and every other arm's paired difference with it; blanks on a map without one."""
    own = result.get("own_specialist")
    if own is None:
        return ["", *("" for _ in names)]
    first = own if own in names else _seed_cell(result["arms"][own]["team_success"])
    return [first, *("" if n == own else _points(result["paired"][f"{n} - {OWN}"])
                     for n in names)]


def summary_rows(name: str, results: Sequence[Mapping[str, Any]],
                 document: Mapping[str, Any]) -> list[list[str]]:
    """Per arm on one set: its team success over the maps (the mean and the interquartile
    mean of every seed's score on every map, with stratified-bootstrap intervals: seeds
    resampled within each map), the probability that it beats the reference on a map
    (:func:`~sgjax.evaluation.statistics.improvement_over_cells`), the maps where it beats
    Only Local, those where it is within the margin of the reference and those where it is
    within the margin of the map's own specialist (of the maps that have one, the arm's own
    map aside)."""
    reference, margin = document["reference"], document["margin"]
    cells = {arm: {r["name"]: _seed_means(r["arms"][arm]["team_success"]) for r in results}
             for arm in document["arms"]}
    rows = []
    for arm in document["arms"]:
        agg = aggregate_over_cells(cells[arm], resamples=RESAMPLES // 2)
        beats = sum(_above(r["paired"][f"{arm} - only_local"], 0.0) for r in results)
        near = better = ""
        if reference is not None and arm != reference:
            near = (f"{sum(_above(r['paired'][f'{arm} - {reference}'], -margin) for r in results)}"
                    f" of {len(results)}")
            p = improvement_over_cells(cells[arm], cells[reference], resamples=RESAMPLES // 2)
            better = f"{p['probability']:.2f} [{p['low']:.2f}, {p['high']:.2f}]"
        owned = [r for r in results if r.get("own_specialist") not in (None, arm)]
        near_own = (f"{sum(_above(r['paired'][f'{arm} - {OWN}'], -margin) for r in owned)} "
                    f"of {len(owned)}" if owned else "")
        rows.append([name, arm, f"{agg['mean']:.2f} [{agg['mean_low']:.2f}, "
                     f"{agg['mean_high']:.2f}]", f"{agg['iqm']:.2f} [{agg['iqm_low']:.2f}, "
                     f"{agg['iqm_high']:.2f}]", better, f"{beats} of {len(results)}", near,
                     near_own])
    return rows


def tables(document: Mapping[str, Any]) -> str:
    """``transfer.md`` from a ``sgjax.transfer/1`` document."""
    arms, reference = document["arms"], document["reference"]
    robots, margin = document["robots"], document["margin"]
    text = [
        "# Transfer: trained policies on worlds they never trained on", "",
        f"{document['episodes']} episodes per map at {robots} robots (fewer where a map has no "
        "room: marked), the same episodes for every seed of every arm and for Only Local. "
        "Team success: the mean over seeds of each seed's mean [95% percentile-bootstrap "
        "interval over seeds]. Paired differences in percentage points, mean [95% interval, "
        "seeds and episodes resampled together]; an arm beats Only Local on a map where its "
        f"interval lies above 0, and is within {margin:g} of the reference "
        f"({reference}) where the interval's low end lies above -{100 * margin:g}. The "
        "summary: each arm's team success over a set's maps (the mean and the interquartile "
        "mean of every seed's score on every map, 95% stratified-bootstrap intervals: seeds "
        "resampled within each map) and its probability of beating the reference on a map "
        "(rliable's probability of improvement, with its interval). Arms: "
        + "; ".join(f"**{n}** {a['seeds']} seeds trained on {', '.join(a['trained_on'])}"
                    for n, a in arms.items()) + "."
        + ("" if not document.get("specialists") else
           f" A shipped map's **{OWN}** is the run trained on it alone (an arm, or "
           + ", ".join(f"{n}: {a['seeds']} seeds" for n, a in document["specialists"].items())
           + ", played on their own map only); an arm is within "
           f"{margin:g} of it where the paired interval's low end lies above "
           f"-{100 * margin:g}."), ""]
    pending = document.get("pending", [])
    if pending:
        text += [f"**In progress**: {len(pending)} map(s) still to play "
                 f"({', '.join(pending[:6])}{', ...' if len(pending) > 6 else ''}).", ""]
    summary = []
    for name in document["sets"]:
        results = [r for r in document["maps"].values() if r["set"] == name]
        if results:
            text += set_section(name, results, document)
            summary += summary_rows(name, results, document)
    gap = generalisation_gap(document)
    if gap:
        text += ["## Generalisation gap (train split - test split, team success points)", "",
                 *markdown_table(["family", *arms], gap), ""]
    if document.get("worst"):
        text += worst_section(document["worst"])
    text += ["## Summary", "", *markdown_table(
        ["set", "arm", "team success, mean", "IQM", f"P(arm > {reference})",
         "beats Only Local", f"within {margin:g} of {reference}",
         f"within {margin:g} of the map's {OWN}"], summary), ""]
    return "\n".join(text)


def _above(summary: Mapping[str, Any], low: float) -> bool:
    return summary["ci_low"] is not None and summary["ci_low"] > low


def generalisation_gap(document: Mapping[str, Any]) -> list[list[str]]:
    """Per family judged on both splits: each arm's team success on the train split less
    the test split's (percentage points)."""
    maps = document["maps"]
    rows = []
    for family in FAMILIES:
        train = maps.get(f"generated_train/{family}")
        test = maps.get(f"generated_test/{family}")
        if train is not None and test is not None:
            rows.append([family, *(f"{100 * (_team(train, n) - _team(test, n)):+.0f}"
                                   for n in document["arms"])])
    return rows


def _record(arm: Arm) -> dict[str, Any]:
    return {"checkpoint": str(arm.path), "sha256": arm.sha256, "seeds": arm.seeds,
            "trained_on": list(arm.trained_on), "deterministic": arm.deterministic,
            "options": arm.options.to_dict()}


def document(arms: Sequence[Arm], maps: Mapping[str, Any], sets: Sequence[str], robots: int,
             episodes: int, seed: int, reference: str | None, margin: float,
             seconds: float, specialists: Sequence[Arm] = ()) -> dict[str, Any]:
    """The ``sgjax.transfer/1`` document: every map's values and paired comparisons, the
    arms' records (and those of the own specialists that are no arm) and provenance."""
    records = {a.name: _record(a) for a in arms}
    judged = {key: {**r, "paired": comparisons(r, reference)} for key, r in maps.items()}
    made = provenance({"arms": {a.name: a.sha256 for a in [*arms, *specialists]},
                       "episodes": episodes,
                       "seed": seed, "sets": list(sets), "robots": robots},
                      seeds={"evaluation": [seed]}, episodes_per_cell=episodes,
                      seconds={"judge": seconds})
    return {"schema_version": TRANSFER, "provenance": made, "arms": records,
            "reference": reference, "margin": margin, "robots": robots, "episodes": episodes,
            "seed": seed, "sets": list(sets), "maps": judged,
            "specialists": {a.name: _record(a) for a in specialists}}


def parser() -> argparse.ArgumentParser:
    """The command line of ``python -m train.transfer``."""
    parser = argparse.ArgumentParser(
        prog="python -m train.transfer",
        description="Judge trained runs on held-out worlds (generated splits, parameter "
                    "extrapolation, the shipped maps, SocialGym 2.0's maps) beside Only "
                    "Local, with paired intervals over seeds and episodes.")
    parser.add_argument("--arm", action="append", default=[], metavar="NAME=RUN",
                        help="a trained run (folder or checkpoint file) and its name "
                             "(repeatable; every arm needs the same make options but terms)")
    parser.add_argument("--own-specialist", action="append", default=[],
                        metavar="ARM_OR_RUN",
                        help="an arm's name, or a run trained on one shipped map alone "
                             "(minigames, office; played on that map only): the map's own "
                             "specialist, which every arm is compared with there (repeatable: "
                             "one per map)")
    parser.add_argument("--reference", default=None,
                        help="the arm the others are compared with (default: the first)")
    parser.add_argument("--sets", nargs="+", default=list(DEFAULT_SETS), choices=SETS,
                        help="held-out sets to judge (default: all but recorded and "
                             "simulated_crowds)")
    parser.add_argument("--robots", type=int, default=4, help="robots per episode")
    parser.add_argument("--episodes", type=int, default=100, help="episodes per map")
    parser.add_argument("--seed", type=int, default=0, help="evaluation seed")
    parser.add_argument("--margin", type=float, default=0.05,
                        help="'within margin of the reference' (team success, 0-1)")
    parser.add_argument("--worst-worlds", type=int, default=0, metavar="N",
                        help="also play N held-out worlds of every generated family twice per "
                             "seed of every arm and report the worst alpha%% (SFL's worst "
                             "case; one compile per family; default 0: off)")
    parser.add_argument("--alpha", type=float, nargs="+", default=[0.1],
                        help="the worst-case fractions (with --worst-worlds)")
    parser.add_argument("--sg2maps", default=str(SG2MAPS),
                        help="SocialGym 2.0's map folders (the sg2maps set)")
    parser.add_argument("--recordings", default=str(RECORDINGS),
                        help="the ETH/UCY track files (the recorded set)")
    parser.add_argument("--out", default=None, help="folder for transfer.json and .md")
    parser.add_argument("--resume", action="store_true",
                        help="keep the maps of <out>/transfer.json (made with the same "
                             "episodes, seed, robots and make options): only maps not yet "
                             "judged, and arms added or retrained since, are played")
    parser.add_argument("--from-results", default=None, metavar="TRANSFER_JSON",
                        help="only write transfer.md again from a transfer.json")
    add_cache_arguments(parser)
    return parser


def _arm_specs(values: Sequence[str]) -> dict[str, str]:
    specs: dict[str, str] = {}
    for value in values:
        name, sep, path = value.partition("=")
        if not sep or not name or not path:
            raise ValueError(f"--arm {value!r}: expected NAME=RUN")
        if name in specs or name == "only_local":
            raise ValueError(f"--arm {value!r}: the name {name!r} is taken")
        specs[name] = path
    return specs


def _own_specialist_runs(values: Sequence[str], arms: Sequence[Arm],
                         maps: Sequence[HeldOutMap]) -> tuple[list[Arm], dict[str, Arm]]:
    """``--own-specialist``'s runs that are no arm (loaded) and every map's own specialist
    (:func:`own_specialists`); names that clash are refused."""
    names = {a.name for a in arms}
    extra = [load_arm(_run_name(value), value) for value in values if value not in names]
    taken = [a.name for a in extra if a.name in names or a.name == "only_local"]
    if taken or len({a.name for a in extra}) < len(extra):
        raise ValueError("--own-specialist: run folder names must differ from each other and "
                         f"from the arms' names ({', '.join(taken)})")
    by_name = {a.name: a for a in [*arms, *extra]}
    return extra, own_specialists([by_name[v if v in names else _run_name(v)]
                                   for v in values], maps)


def _run_name(value: str) -> str:
    """An own specialist's name: its run folder's name (or a checkpoint file's stem)."""
    path = Path(value)
    return path.name if path.is_dir() else path.stem


def read_earlier(out: Path, wanted: Mapping[str, Any]) -> dict[str, Any]:
    """Every map result of ``out/transfer.json`` (complete and incomplete: ``maps`` and
    ``unfinished``) when it was made with the same :func:`settings` (``wanted``); an error
    naming the setting that differs otherwise."""
    path = out / "transfer.json"
    if not path.is_file():
        return {}
    data = json.loads(path.read_text())
    arms = list(data.get("arms", {}).values())
    made = {"options": _shared_part(MakeOptions.from_dict(arms[0]["options"])) if arms
            else None, "episodes": data.get("episodes"), "seed": data.get("seed"),
            "robots": data.get("robots")}
    differ = [name for name in wanted if made[name] != wanted[name]]
    if differ:
        raise ValueError(f"{path}: made with other {', '.join(differ)} (the episodes would "
                         "differ); delete it or run without --resume")
    return {**data.get("unfinished", {}), **data["maps"]}


def _checked_arguments(args: argparse.Namespace) -> tuple[dict[str, str], str]:
    """``(arms {name: run}, reference arm)`` of the command line, or an error naming the
    argument that is wrong."""
    specs = _arm_specs(args.arm)
    if not specs:
        raise ValueError("give at least one --arm NAME=RUN")
    reference = args.reference or next(iter(specs))
    if reference not in specs:
        raise ValueError(f"--reference {reference!r} is not one of the arms "
                         f"{', '.join(specs)}")
    if args.robots < 1 or args.episodes < 1 or not 0 < args.margin < 1:
        raise ValueError("--robots and --episodes must be at least 1, --margin in (0, 1)")
    if args.resume and args.out is None:
        raise ValueError("--resume needs --out")
    if args.worst_worlds < 0 or not all(0 < a <= 1 for a in args.alpha):
        raise ValueError("--worst-worlds must be at least 0 and every --alpha in (0, 1]")
    return specs, reference


def main(argv: list[str] | None = None) -> None:
    args = parser().parse_args(argv)
    try:
        if args.from_results is not None:
            source = Path(args.from_results)
            target = source.with_name("transfer.md")
            write_atomic(target, tables(json.loads(source.read_text())))
            print(f"wrote {target}")
            return
        cache_from_arguments(args)
        specs, reference = _checked_arguments(args)
        arms = [load_arm(name, path) for name, path in specs.items()]
        maps = held_out_maps(args.sets, args.robots, Path(args.sg2maps), Path(args.recordings))
        extra, own = _own_specialist_runs(args.own_specialist, arms, maps)
        out = None if args.out is None else Path(args.out)
        reference_seeds = next(a.seeds for a in arms if a.name == reference)
        for arm in [*arms, *extra]:  # seeds pair by index with the reference's
            if arm.seeds != reference_seeds:
                raise ValueError(f"{arm.name} has {arm.seeds} seeds and the reference "
                                 f"{reference} {reference_seeds}: a paired comparison needs "
                                 "as many seeds in each")
        wanted_settings = settings(arms, args.episodes, args.seed, args.robots)
        done = read_earlier(out, wanted_settings) if args.resume and out is not None else {}
        before = (json.loads((out / "transfer.json").read_text())
                  if done and out is not None else {})
        earlier_worst = before.get("worst")
        worst = earlier_worst
        log = functools.partial(print, flush=True)
        if done:
            log(f"resuming {out}: {len(done)} map(s) judged before")

        start = time.perf_counter()
        played = []  # maps this process played

        def write(results: Mapping[str, Any]) -> str:  # tables of the maps every arm played
            judged = {m.key: results[m.key] for m in maps
                      if is_complete(results.get(m.key), arms, own.get(m.key))}
            made = document(arms, judged, args.sets, args.robots, args.episodes, args.seed,
                            reference, args.margin, time.perf_counter() - start, extra)
            if not played and before.get("provenance", {}).get("config_sha256") == \
                    made["provenance"].get("config_sha256"):
                # nothing played here: the maps' values are the earlier run's, and so is
                # their provenance (the worst case carries its own)
                made["provenance"] = before["provenance"]
            made["pending"] = [m.key for m in maps if m.key not in judged]
            if worst is not None:
                made["worst"] = worst
            # kept for a later --resume: maps some arm has not played yet, other sets' maps
            made["unfinished"] = {k: v for k, v in results.items() if k not in judged}
            text = tables(made)
            if out is not None:
                out.mkdir(parents=True, exist_ok=True)
                write_atomic(out / "transfer.json", json.dumps(made, indent=1) + "\n")
                write_atomic(out / "transfer.md", text)
            return text

        def keep(key: str, result: dict) -> None:
            done[key] = result
            played.append(key)
            write(done)

        results = judge(arms, maps, args.episodes, args.seed, done, keep, log, own)

        def keep_worst(block: dict[str, Any]) -> None:
            nonlocal worst
            worst = block
            write(results)

        if args.worst_worlds:
            worst = judge_worst(arms, args.robots, args.worst_worlds, args.alpha, args.seed,
                                earlier_worst, log, keep_worst)
        text = write(results)
        if out is not None:
            log(f"wrote {out / 'transfer.json'}, {out / 'transfer.md'}")
        print("\n" + text)
    except ValueError as err:
        raise SystemExit(f"transfer: {err}") from err


if __name__ == "__main__":
    main()
