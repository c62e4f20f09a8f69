"""Reward and observation ablations trained as lanes of one function (the paper's Table 5).

A *variant* switches reward terms off (a multiplier of 0 on ``info["reward_terms"]``) and hides
observation features (a 0 in the observation mask). Reward weights and the mask are arrays in
the runner state, so every variant x seed is one lane of one jitted training function (in one
call, or in groups of lanes; ``algorithm.lanes`` says how the lanes run); only the network
architecture (MLP or GRU) needs its own.

    variants = {"baseline": Variant(), "no collision": Variant(rewards_off=("collision",)),
                "no velocities": Variant(hide=("velocity", "others.velocity"))}
    trainer = Trainer(config)
    runner, logs = train_variants(trainer, variants, seeds=3)

Command line (the paper's Table 5 variants, or a variants file; prints the table)::

    python -m train.ablation --config train/configs/ablation.yaml --seeds 3 --lanes-per-run 24

A variants file maps names to ``rewards_off``, ``hide``, ``network`` (keys of the config's
``network`` section) and ``set`` (any other config keys, ``section.key: value`` as ``--set``
takes them); a variant with its own network or settings trains as its own vmap::

    baseline: {}
    no collision penalty: {rewards_off: [collision]}
    no velocities: {hide: [velocity, others.velocity]}
    GRU: {network: {kind: gru}}
    own reward: {set: {algorithm.team_reward: 0.0}}

A variant's ``levels`` (``dr``, ``plr``, ``accel``, ``learnability``) trains it under that
curriculum over generated worlds, as a lane beside the others (the config's ``levels``
section active; ``train/configs/variants/transfer_curriculum-methods.yaml``).

``--robots 4 7`` evaluates every lane at each count (one compiled evaluation) and prints a table
per count.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import hashlib
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from sgjax.compilation_cache import add_cache_arguments, cache_from_arguments
from sgjax.evaluation.provenance import cpu_model, provenance, run_git_state
from sgjax.evaluation.report import format_points, format_summary, markdown_table
from sgjax.evaluation.statistics import paired_difference, probability_of_improvement, summarize
from sgjax.evaluation.trained import TrainedEvaluation
from sgjax.files import write_atomic
from sgjax.terms.base import ConfigError
from sgjax.validation import check_keys, freeze, thaw
from train.algorithm.actor import ActorWeights
from train.algorithm.config import (
    CURRICULA,
    EVALUATION_SEED_OFFSET,
    TrainConfig,
    as_trained,
    config_from_dict,
    load_config,
    read_yaml,
)
from train.algorithm.env_batch import observation_mask
from train.algorithm.trainer import Trainer
from train.reports.result_schemas import ABLATION
from train.run import checkpoint
from train.run.loop import Call, equal_calls, train_in_calls
from train.run.multiprocess import Processes, add_arguments, gather_lanes, initialize, lane_share
from train.run.partial import SAVES_PER_RUN, PartialFile
from train.run.phases import Phases


@dataclasses.dataclass(frozen=True)
class Variant:
    """Reward terms to switch off, and observation features to hide: a term name
    (``"velocity"``) or ``"<term>.<feature>"``, one feature of a term in every block (body,
    step, beam) as its published column layout names it: ``"others.velocity"`` (every body's
    velocity), ``"pose.heading"`` (the pose's cos/sin)."""

    rewards_off: tuple[str, ...] = ()
    hide: tuple[str, ...] = ()
    network: tuple[tuple[str, Any], ...] = ()  # (key, value) of the network section to change
    settings: tuple[tuple[str, Any], ...] = ()  # ("section.key", value): other config keys
    # a curriculum over generated worlds (dr, plr, accel, learnability) followed as a lane of
    # the config's own (its levels section active); None: the config's method
    levels: str | None = None


def variant_inputs(trainer: Trainer, variants: Mapping[str, Variant], seeds: int
                   ) -> tuple[jax.Array, dict, jax.Array, dict, list[tuple[str, int]]]:
    """Keys, term weights, masks and curriculum numbers stacked over lanes (variant x seed),
    and the lane labels (a variant's terms off and features hidden on top of the config's
    ``term_weights`` and ``hide``; its ``levels`` method's numbers,
    :meth:`Trainer.curriculum_values`)."""
    names = trainer.batch.reward_term_names()
    configured = trainer.term_weights()
    hidden = trainer.config.algorithm.hide
    keys, weights, masks, curricula, labels = [], [], [], [], []
    for label, variant in variants.items():
        try:
            curriculum = trainer.curriculum_values(variant.levels)
        except ConfigError as err:
            raise ConfigError(f"variant {label!r}: {err}") from None
        for off in variant.rewards_off:
            if off not in names:
                raise ConfigError(f"variant {label!r}: no reward term {off!r}; this "
                                  f"configuration pays {list(names)}")
        mask = observation_mask(trainer.batch.env, (*hidden, *variant.hide))
        for seed in range(seeds):
            keys.append(jax.random.PRNGKey(trainer.config.seed + seed))
            weights.append({n: 0.0 if n in variant.rewards_off else float(configured[n])
                            for n in names})
            masks.append(mask)
            curricula.append(curriculum)
            labels.append((label, seed))
    stacked = {n: jnp.asarray([w[n] for w in weights]) for n in names}
    lanes = {n: jnp.asarray([c[n] for c in curricula]) for n in curricula[0]}
    return jnp.stack(keys), stacked, jnp.asarray(np.stack(masks)), lanes, labels


def train_variants(trainer: Trainer, variants: Mapping[str, Variant], seeds: int,
                   lanes_per_run: int | None = None, lanes: Sequence[int] | None = None,
                   partial: Path | None = None, resume: bool = False
                   ) -> tuple[Any, dict, list[tuple[str, int]]]:
    """Train every variant x seed as lanes of one jitted function
    (:func:`train.run.loop.train_in_calls`): all lanes in one call, or ``lanes_per_run`` lanes
    at a time (the same compiled function for every group, the last group padded; for
    memory). ``lanes`` picks some of the lanes (indices into the variant x seed order; this
    process's share of a multi-process sweep). Returns the lane-batched runner, the per-update
    logs ``[lanes, updates]`` and the lane labels ``(variant, seed)``.

    Each call of lanes trains in calls of equal numbers of updates, and with ``partial`` (a
    file path, :class:`train.run.partial.PartialFile`) is saved there about ten times (the
    runners and logs of the lane calls so far); a ``resume`` run finding the file continues
    from it (the same trainer config and lanes, or an error naming the file); a run without
    ``resume`` deletes a file it finds, and the caller deletes it once the group's scores are
    kept."""
    keys, weights, masks, curricula, labels = variant_inputs(trainer, variants, seeds)
    if lanes is not None:
        index = np.asarray(lanes, int)
        if not len(index):
            raise ValueError("train_variants: no lanes to train")
        keys, masks = keys[index], masks[index]
        weights, curricula = jax.tree.map(lambda x: x[index], (weights, curricula))
        labels = [labels[i] for i in index]
    updates = trainer.config.algorithm.num_updates
    count = len(labels)
    width = count if lanes_per_run is None else max(1, min(lanes_per_run, count))
    per_call = equal_calls(updates, SAVES_PER_RUN)
    start = jax.jit(jax.vmap(lambda k, w, m, c: trainer.init(k, w, m, curriculum=c)))
    runs = [np.minimum(np.arange(first, first + width), count - 1)
            for first in range(0, count, width)]  # the last run padded
    inputs = [jax.tree.map(lambda x, index=index: x[index], (keys, weights, masks, curricula))
              for index in runs]
    file = PartialFile(partial, trainer.config, "group", resume=resume, saves=SAVES_PER_RUN, meta={
        "labels": [list(label) for label in labels], "width": width, "per_call": per_call,
        "of": updates})
    trained: list[tuple[Any, dict]] = []  # (runner, logs [width, updates done]) per run
    done = 0  # updates done in the last of ``trained``
    loaded = file.load(functools.partial(_lane_calls, jax.eval_shape(start, *inputs[0])))
    if loaded is not None:
        trained, done = loaded
        print(f"    resuming {partial} at update {done} of {updates} of lane call "
              f"{len(trained)} of {len(runs)}", flush=True)
    for number, args in enumerate(inputs):
        if number == len(trained):
            trained.append((start(*args), {}))
            done = 0
        elif number < len(trained) - 1 or done == updates:
            continue

        def keep(call: Call, number: int = number) -> None:
            logs = trained[number][1]
            trained[number] = (call.runner, call.logs if not logs else jax.tree.map(
                lambda a, b: jnp.concatenate([a, b], axis=1), logs, call.logs))
            file.save_if_due({str(i): {"runner": r, "logs": g}
                              for i, (r, g) in enumerate(trained)}, call.done, per_call, updates)

        train_in_calls(trainer, trained[number][0], per_call, updates, done=done,
                       after_call=keep)
    runner, logs = jax.tree.map(lambda *xs: jnp.concatenate(xs)[:count], *trained)
    return runner, logs, labels


def _lane_calls(template: Any, raw: dict) -> list[tuple[Any, dict]]:
    """The lane calls of a group's partial file (:func:`train_variants`): their runners
    (``template``'s shapes) and logs."""
    trained = []
    for number in range(len(raw)):
        entry = raw[str(number)]
        runner = checkpoint.state_from_raw(template, entry["runner"])
        logs = {name: jnp.asarray(value) for name, value in entry["logs"].items()}
        trained.append((jax.tree.map(jnp.asarray, runner), logs))
    return trained


def score_lanes(trainer: Trainer, runner: Any, scenario: str, counts: Sequence[int],
                episodes: int, key: jax.Array) -> np.ndarray:
    """Team success of every lane over ``episodes`` episodes of ``scenario`` at each robot
    count, actions sampled: ``[counts, lanes]`` (one compiled evaluation,
    :class:`sgjax.evaluation.trained.TrainedEvaluation`)."""
    evaluation = TrainedEvaluation(trainer.trained_actor, scenario, counts, episodes,
                                   trainer.config.env.options,
                                   max_agents=max(*counts, trainer.slots))
    return evaluation.scores(ActorWeights.of(runner), key, "team_success")


# The paper's Table 5 (intersection, 4 robots): a change from its PPO baseline, and the
# percentage of seed runs that did better than the baseline. Its "entropy penalty" is
# SocialGym's stuck detector (sgjax's ``stuck`` penalty), "thetas" the headings, and its
# LSTM policy is LSTM-PPO as sb3-contrib builds it (an LSTM of 256 over time in the actor and
# in the critic; a GRU remains a network option); its clipped goal distance is approximated by
# hiding the distance, and its entropy reward multiplier has no sgjax counterpart.
PAPER_VARIANTS: dict[str, tuple[Variant, int | None]] = {
    "baseline": (Variant(), None),
    "LSTM-PPO": (Variant(network=(("kind", "lstm"), ("recurrent_size", 256))), 76),
    "no goal distance (paper: clipped)": (Variant(hide=("goal_distance",)), 0),
    "no collision penalty": (Variant(rewards_off=("collision",)), 84),
    "no existence penalty": (Variant(rewards_off=("existence",)), 44),
    "no stuck penalty (paper: entropy)": (Variant(rewards_off=("stuck",)), 52),
    "no velocities": (Variant(hide=("velocity", "others.velocity")), 0),
    "no headings (paper: thetas)": (Variant(hide=("pose.heading", "others.heading")), 0),
}
BASELINE = "baseline"


def load_variants(path: str | Path) -> dict[str, Variant]:
    """Variants from a YAML file (see the module docstring); errors name the file and key."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: no such variants file")
    data = read_yaml(path.read_text()) or {}
    if not isinstance(data, Mapping) or not data:
        raise ConfigError(f"{path}: expected a mapping of variant names to settings")
    fields = ("rewards_off", "hide", "network", "set", "levels")
    variants = {}
    for name, spec in data.items():
        spec = spec or {}
        if not isinstance(spec, Mapping):
            raise ConfigError(f"{path}: {name}: expected a mapping with {', '.join(fields)}")
        try:
            check_keys(f"{path}: {name}", spec, fields)
        except ValueError as err:
            raise ConfigError(str(err)) from None
        lists = {}
        for key in ("rewards_off", "hide"):
            value = spec.get(key, [])
            if isinstance(value, str) or not all(isinstance(v, str) for v in value):
                raise ConfigError(f"{path}: {name}.{key}: expected a list of names")
            lists[key] = tuple(value)
        network = spec.get("network", {})
        if not isinstance(network, Mapping):
            raise ConfigError(f"{path}: {name}.network: expected a mapping of network keys")
        settings = spec.get("set", {})
        if not isinstance(settings, Mapping) or not all(
                isinstance(k, str) and "." in k for k in settings):
            raise ConfigError(f"{path}: {name}.set: expected a mapping of section.key: value")
        levels = spec.get("levels")
        if levels is not None and levels not in CURRICULA:
            raise ConfigError(f"{path}: {name}.levels: expected one of {list(CURRICULA)}, "
                              f"got {levels!r}")
        # values frozen (sgjax.validation.freeze): variants group by them
        variants[str(name)] = Variant(**lists, network=tuple(sorted(freeze(network).items())),
                                      settings=tuple(sorted(freeze(settings).items())),
                                      levels=levels)
    if BASELINE not in variants:
        raise ConfigError(f"{path}: no {BASELINE!r} variant (the others are compared to it)")
    return variants


def _variant_config(config: TrainConfig, variant: Variant, seeds: int) -> TrainConfig:
    """``config`` with ``seeds`` seeds and a variant's network keys and settings changed."""
    data = config.to_dict()
    data["num_seeds"] = seeds
    data["network"] = {**data["network"], **thaw(dict(variant.network))}
    for key, value in variant.settings:
        section, _, field = key.partition(".")
        if not isinstance(data.get(section), dict):
            raise ConfigError(f"variant setting {key!r}: {section!r} is not a config section")
        data[section] = {**data[section], field: thaw(value)}
    where = f"variant network {dict(variant.network)}, settings {dict(variant.settings)}"
    return config_from_dict(data, where)


def variant_groups(variants: Mapping[str, Variant], per_group: int | None = None
                   ) -> list[dict[str, Variant]]:
    """The variants that train as one vmap: those with the same network and settings, in
    order of first appearance; with ``per_group``, each such set cut into consecutive groups
    of at most that many variants (smaller groups finish, and are kept in the partial result,
    sooner: a long run then loses less when it is stopped)."""
    if per_group is not None and per_group < 1:
        raise ValueError(f"variants per group must be at least 1, got {per_group}")
    kinds: dict[tuple, dict[str, Variant]] = {}
    for name, variant in variants.items():
        kinds.setdefault((variant.network, variant.settings), {})[name] = variant
    groups = []
    for kind in kinds.values():
        names = list(kind)
        size = per_group or len(names)
        groups += [{name: kind[name] for name in names[i:i + size]}
                   for i in range(0, len(names), size)]
    return groups


def group_name(group: Mapping[str, Variant]) -> str:
    """A group's key in a partial result: its variants' names."""
    return " | ".join(group)


def run_ablation(config: TrainConfig, variants: Mapping[str, Variant], seeds: int,
                 lanes_per_run: int | None, episodes: int, robots: int | Sequence[int],
                 log=print, processes: Processes | None = None,
                 done: Mapping[str, Mapping[str, Any]] | None = None,
                 on_group=None, partial_dir: Path | None = None, resume: bool = False,
                 variants_per_group: int | None = None) -> dict:
    """Train every variant x seed (one vmap per network architecture and settings), evaluate
    every lane on the config's first scenario with ``robots`` robots (one count or several:
    one compiled evaluation serves them all); returns ``{"scores": {variant: [seeds]},
    "scores_by_robots": {count: {variant: [seeds]}}, "seconds": {phase: s}}`` (team success per
    seed; ``scores`` at the first count). Under several ``processes`` each trains and evaluates
    its share of every group's lanes and the scores are gathered, so every process returns the
    whole sweep's.

    ``done`` (``{group_name: {"scores": {count: {variant: [seeds]}}, "seconds": {...}}}``, a
    partial run's finished groups) skips those groups' training; ``on_group(name, record)`` is
    called with each newly finished group's record (for a partial result file).
    ``partial_dir``: each group's lanes checkpoint there while they train
    (``group-<n>.msgpack``, :func:`train_variants`), continued when ``resume``; a group's file
    is deleted once ``on_group`` kept its record. ``variants_per_group``: see
    :func:`variant_groups` (the groups of one network and settings share their trainer)."""
    processes = processes or Processes()
    done = dict(done or {})
    counts = [robots] if isinstance(robots, int) else [int(n) for n in robots]
    groups = variant_groups(variants, variants_per_group)
    trainers = group_trainers(config, groups, seeds)
    scores: dict[int, dict[str, list[float]]] = {n: {} for n in counts}
    phases = Phases("compile and train", "evaluate")
    for index, (group, trainer) in enumerate(zip(groups, trainers, strict=True)):
        name_of_group = group_name(group)
        where = f"group {index + 1} of {len(groups)} ({', '.join(group)}"
        if name_of_group in done:
            record = done[name_of_group]
            log(f"{where}): kept from the partial run")
        else:
            log(f"{where}; network {trainer.config.network.kind}): training "
                f"{len(group) * seeds} lanes of {trainer.config.algorithm.total_steps:,} "
                "environment steps")
            lane_file = None if partial_dir is None else partial_dir / f"group-{index + 1}.msgpack"
            record = train_group(trainer, group, seeds, lanes_per_run, episodes, counts,
                                 processes, lane_file, resume, log)
            if on_group is not None:
                on_group(name_of_group, record)
            if lane_file is not None:
                lane_file.unlink(missing_ok=True)
        for n in counts:
            for name in group:
                scores[n][name] = [float(v) for v in record["scores"][str(n)][name]]
        for phase, value in record["seconds"].items():
            phases.add(phase, value)
    by_robots = {n: {name: scores[n][name] for name in variants} for n in counts}
    return {"scores": by_robots[counts[0]], "scores_by_robots": by_robots,
            "seconds": phases.seconds}


def group_trainers(config: TrainConfig, groups: Sequence[Mapping[str, Variant]], seeds: int
                   ) -> list[Trainer]:
    """Every group's trainer, one per network and settings (config, environment and network
    built, nothing compiled): a bad variant fails before any training."""
    by_kind: dict[tuple, Trainer] = {}
    trainers = []
    for group in groups:
        first = next(iter(group.values()))
        kind = (first.network, first.settings)
        if kind not in by_kind:
            by_kind[kind] = Trainer(_variant_config(config, first, seeds))
        trainers.append(by_kind[kind])
    return trainers


def train_group(trainer: Trainer, group: Mapping[str, Variant], seeds: int,
                lanes_per_run: int | None, episodes: int, counts: Sequence[int],
                processes: Processes, lane_file: Path | None, resume: bool, log
                ) -> dict[str, Any]:
    """Train and evaluate one group's lanes (this process's share of them; the scores
    gathered from every process): its record, ``{"scores": {count: {variant: [seeds]}},
    "seconds": {phase: s}, "git", "cpu"}``."""
    config = trainer.config
    labels = [(name, seed) for name in group for seed in range(seeds)]
    share = lane_share(len(labels), processes)
    phases = Phases("compile and train", "evaluate")
    team = np.zeros((len(counts), 0))
    if len(share):
        with phases.timing("compile and train"):
            runner, _, _ = train_variants(trainer, group, seeds, lanes_per_run, share,
                                          partial=lane_file, resume=resume)
        with phases.timing("evaluate"):
            team = score_lanes(trainer, runner, config.env.scenarios[0], counts, episodes,
                               jax.random.PRNGKey(config.seed + EVALUATION_SEED_OFFSET))
    scores: dict[str, dict[str, list[float]]] = {str(n): {} for n in counts}
    for n, row in zip(counts, team, strict=True):
        for (name, _), value in zip(labels, gather_lanes(row, len(labels), processes),
                                    strict=True):
            scores[str(n)].setdefault(name, []).append(float(value))
    seconds = phases.seconds
    where = "" if processes.count == 1 else (
        f" (process {processes.index} of {processes.count}: lanes {share.tolist()})")
    log(f"trained and evaluated {len(share)} of {len(labels)} lanes ({', '.join(group)}; "
        f"network {config.network.kind}) in {seconds['compile and train']:.0f} s + "
        f"{seconds['evaluate']:.0f} s{where}")
    # a resumed run's groups may come from other commits or machines
    return {"scores": scores, "seconds": seconds, "git": run_git_state(), "cpu": cpu_model()}


PARTIAL = "ablation.partial.json"
LANE_PARTIALS = "ablation.partial"  # the folder of the running group's lane checkpoints


def run_fingerprint(config: TrainConfig, variants: Mapping[str, Variant], seeds: int,
                    episodes: int, counts: Sequence[int], variants_per_group: int | None = None
                    ) -> str:
    """A hash of everything that decides a run's scores: a partial result is resumed only by
    the run that wrote it (the grouping too: lanes batched differently round differently)."""
    described = {"config": as_trained(config.to_dict()), "seeds": seeds, "episodes": episodes,
                 "robots": [int(n) for n in counts],
                 "variants": {name: dataclasses.asdict(v) for name, v in variants.items()}}
    if variants_per_group is not None:  # absent otherwise: earlier partial results still fit
        described["variants_per_group"] = variants_per_group
    text = json.dumps(described, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def read_partial(path: Path, fingerprint: str) -> dict[str, Any]:
    """The finished groups of a partial result file (``{}`` when there is none), or an error
    naming the file when it is unreadable or was written by a run with other arguments."""
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text())
        groups, written = data["groups"], data["fingerprint"]
    except (ValueError, KeyError, TypeError) as err:
        raise ConfigError(f"{path}: not a partial ablation result ({err}); delete it to start "
                          f"afresh") from None
    if written != fingerprint:
        raise ConfigError(f"{path}: written by a run with another config, variants, seeds, "
                          f"episodes or robot counts; rerun with those, or delete the file")
    return groups


def paired_against_baseline(scores: Mapping[str, list[float]]) -> dict[str, dict]:
    """Each variant against the baseline over training seeds: the per-seed difference (seed i
    of both was trained from the same key and evaluated on the same episodes) with its 95%
    Student-t interval, and the probability of improvement (:mod:`sgjax.evaluation.statistics`).
    """
    base = np.asarray(scores[BASELINE], float)
    return {name: {"difference": paired_difference(np.asarray(values, float), base).as_dict(),
                   "probability_of_improvement": probability_of_improvement(values, base)}
            for name, values in scores.items() if name != BASELINE}


def format_table(scores: Mapping[str, list[float]], paper: Mapping[str, int | None],
                 scenario: str, robots: int, episodes: int) -> str:
    """The ablation table as markdown: team success over seeds (mean ± 95% Student-t half
    width), the share of seeds above the baseline's mean and the paper's share (its measure),
    and the paired difference from the baseline over seeds with its interval and the
    probability of improvement."""
    base = float(np.mean(scores[BASELINE]))
    paired = paired_against_baseline(scores)
    rows = []
    for name, values in scores.items():
        beats = "" if name == BASELINE else f"{100 * np.mean(np.asarray(values) > base):.0f}"
        cited = paper.get(name)
        difference = probability = ""
        if name != BASELINE:
            d = paired[name]["difference"]
            difference = format_points(d["mean"], d["ci_low"], d["ci_high"])
            probability = f"{paired[name]['probability_of_improvement']:.2f}"
        rows.append([name, format_summary(summarize(np.asarray(values), binary=False), True),
                     beats, "" if cited is None else str(cited), difference, probability])
    seeds = len(scores[BASELINE])
    title = ("SocialGym 2.0 Table 5 (reward and observation ablation), reproduced with sgjax"
             if paper else "Variants against the baseline")
    lines = [f"# {title}", "",
             f"Team success (%) on {scenario} with {robots} robots, {episodes} episodes per "
             f"seed: the mean over {seeds} seeds ± the half width of its 95% Student-t interval;"
             " seeds beating the baseline: the % of seeds above the baseline's mean (the "
             "paper's measure); paired: the variant's team success minus the baseline's, seed "
             "by seed (the same training key and evaluation episodes), mean [95% Student-t "
             "interval over seeds], in points (an interval that excludes 0 is a difference); "
             "P(improvement): the chance that a random seed of the variant beats a random seed "
             "of the baseline (ties half).", "",
             *markdown_table(["Variant", "Team success (%)", "Seeds beating the baseline (%)",
                              "Paper (%)", "Paired vs baseline (points)", "P(improvement)"],
                             rows)]
    return "\n".join(lines) + "\n"


def table_of(document: Mapping[str, Any]) -> str:
    """``ablation.md`` again from an ``ablation.json`` document (schema :data:`ABLATION`):
    one :func:`format_table` per robot count; the paper's value beside every variant named
    as a row of the paper's Table 5 (:data:`PAPER_VARIANTS`), none for the others (a file of
    another variants set, or an older name)."""
    variants = set(document["variants"])
    paper = {name: cited for name, (_, cited) in PAPER_VARIANTS.items() if name in variants}
    if all(cited is None for cited in paper.values()):
        paper = {}
    scenario = document["config"]["env"]["scenarios"][0]
    return "\n".join(format_table(scores, paper, scenario, int(n), int(document["episodes"]))
                     for n, scores in document["team_success_by_robots"].items())


def parser() -> argparse.ArgumentParser:
    """The command line of ``python -m train.ablation``."""
    parser = argparse.ArgumentParser(
        prog="python -m train.ablation",
        description="Train reward and observation ablations as vmap lanes and print the "
                    "paper's Table 5 (the share of seeds beating the baseline).")
    parser.add_argument("--config", required=True, help="YAML file (train/configs/ablation.yaml)")
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="override one config key (repeatable)")
    parser.add_argument("--variants", default=None,
                        help="YAML variants file (default: the paper's Table 5 variants)")
    parser.add_argument("--seeds", type=int, default=3, help="seeds per variant")
    parser.add_argument("--lanes-per-run", type=int, default=None,
                        help="lanes per compiled call (default: all lanes in one call)")
    parser.add_argument("--variants-per-group", type=int, default=None,
                        help="train at most this many variants (x --seeds lanes) per group; "
                             "default: every variant of one network and settings in one "
                             "group. Smaller groups finish sooner, and --resume keeps every "
                             "finished group (the paper's Table 5 at 10 seeds: its MLP group "
                             "is 70 lanes, hours of CPU)")
    parser.add_argument("--episodes", type=int, default=None,
                        help="evaluation episodes per lane (default: evaluation.episodes)")
    parser.add_argument("--robots", type=int, nargs="+", default=None,
                        help="evaluation robot count(s) (default: the curriculum's last); "
                             "a table per count")
    parser.add_argument("--out", default=None,
                        help="folder for ablation.md and ablation.json (written atomically "
                             "at the end); while it runs, ablation.partial.json keeps every "
                             "finished group of variants (one network and settings: one "
                             "vmap), which --resume reuses")
    parser.add_argument("--resume", action="store_true",
                        help="continue a killed run with the same arguments: the groups in "
                             "<out>/ablation.partial.json are not trained again, and a group "
                             "killed midway continues from its last checkpoint in "
                             "<out>/ablation.partial/ (about ten per group; a run "
                             "of several processes restarts such a group)")
    add_cache_arguments(parser)
    add_arguments(parser)
    return parser


def check_arguments(args: argparse.Namespace, processes: Processes) -> None:
    """Errors for arguments that cannot run (counts below 1, a resume without a folder or
    over several processes)."""
    if args.seeds < 1 or any(value is not None and value < 1 for value in (
            args.lanes_per_run, args.variants_per_group)):
        raise ConfigError("--seeds, --lanes-per-run and --variants-per-group must be at "
                          "least 1")
    if args.robots is not None and min(args.robots) < 1:
        raise ConfigError(f"--robots: counts must be at least 1, got {args.robots}")
    if args.resume and args.out is None:
        raise ConfigError("--resume needs --out (the folder of the run to continue)")
    if args.resume and processes.count > 1:
        raise ConfigError("--resume runs in one process (the partial result is process "
                          "0's); continue without --coordinator")


def write_outputs(out: Path, config: TrainConfig, variants: Mapping[str, Variant],
                  table: str, result: dict, done: Mapping[str, Any], seeds: int,
                  episodes: int, counts: Sequence[int]) -> None:
    """``ablation.md`` and ``ablation.json`` (schema :data:`ABLATION`, with provenance) in
    ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "ablation.md").write_text(table)
    made = provenance(config.to_dict(), seeds={
        "training": [config.seed + i for i in range(seeds)],
        "evaluation": [config.seed + EVALUATION_SEED_OFFSET]},
        episodes_per_cell=episodes, seconds=result["seconds"])
    write_atomic(out / "ablation.json", json.dumps(
        {"schema_version": ABLATION, "provenance": made, "config": config.to_dict(),
         "seeds": seeds, "episodes": episodes, "robots": counts[0],
         "team_success": result["scores"],
         "team_success_by_robots": {str(n): v for n, v in result["scores_by_robots"].items()},
         "paired": {str(n): paired_against_baseline(v) for n, v in
                    result["scores_by_robots"].items()},
         "variants": {name: dataclasses.asdict(v) for name, v in variants.items()},
         "groups": {name: {key: record[key] for key in ("git", "cpu", "seconds")
                           if key in record} for name, record in done.items()},
         "seconds": result["seconds"]}, indent=1))


def main(argv: list[str] | None = None) -> None:
    args = parser().parse_args(argv)
    try:
        cache_from_arguments(args)
        processes = initialize(args.coordinator, args.num_processes, args.process_id)
        check_arguments(args, processes)
        config = load_config(args.config, args.set)
        if args.variants is None:
            variants = {name: v for name, (v, _) in PAPER_VARIANTS.items()}
            paper = {name: cited for name, (_, cited) in PAPER_VARIANTS.items()}
        else:
            variants, paper = load_variants(args.variants), {}
        episodes = args.episodes or config.evaluation.episodes
        counts = args.robots or [config.env.curriculum[-1][1]]
        phases = Phases()
        log = functools.partial(print, flush=True)
        out = None if args.out is None else Path(args.out)
        partial = None if out is None else out / PARTIAL
        fingerprint = run_fingerprint(config, variants, args.seeds, episodes, counts,
                                      args.variants_per_group)
        done = read_partial(partial, fingerprint) if args.resume else {}
        if args.resume:
            log(f"resuming {partial}: {len(done)} finished group(s)")

        def keep(name: str, record: dict) -> None:
            if partial is None or not processes.is_main:
                return
            done[name] = record
            partial.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(partial, json.dumps({"fingerprint": fingerprint, "groups": done},
                                             indent=1))

        lane_files = None if out is None or processes.count > 1 else out / LANE_PARTIALS
        result = run_ablation(config, variants, args.seeds, args.lanes_per_run, episodes,
                              counts, log=log, processes=processes, done=done, on_group=keep,
                              partial_dir=lane_files, resume=args.resume,
                              variants_per_group=args.variants_per_group)
        table = "\n".join(format_table(scores, paper, config.env.scenarios[0], n, episodes)
                          for n, scores in result["scores_by_robots"].items())
        if not processes.is_main:
            print(f"process {processes.index}: done; process 0 writes the table")
            return
        for phase, value in result["seconds"].items():
            phases.add(phase, value)
        with phases.timing("write"):
            if out is not None:
                write_outputs(out, config, variants, table, result, done, args.seeds,
                              episodes, counts)
                partial.unlink(missing_ok=True)
                if lane_files is not None and lane_files.is_dir() and not any(
                        lane_files.iterdir()):
                    lane_files.rmdir()
        print("\n" + table)
        print(phases.line())
    except (ConfigError, ValueError) as err:
        raise SystemExit(f"ablation: {err}") from err


if __name__ == "__main__":
    main()
