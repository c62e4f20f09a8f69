"""``python -m train --config train/configs/doorway.yaml`` (also ``sgjax-train``): train, show
progress, evaluate periodically, keep the best checkpoint, and finish with the metrics table
of the final weights (``evaluation.checkpoint: best`` judges the best checkpoint instead)
beside the baseline and a GIF of an evaluation episode.

Writes into ``logging.out`` (or ``--out``): ``config.yaml``, ``progress.csv`` and its
``learning_curve.png`` (``train.reports.curves``), TensorBoard events under ``tb/``,
``checkpoints/{latest,best}.msgpack``, and ``eval/`` (``metrics.json``,
``metrics.csv``, ``table.md``, charts, ``episode.gif``; with a baseline ``paired.json`` and
``paired.md``: both policies' team success on the same episodes and their paired difference;
with several seeds ``seed_spread.json`` and ``seed_spread.md``) and ``provenance.json``
(commit, versions, machine, command, seeds, phase times). ``--resume`` continues from
``checkpoints/latest.msgpack``; ``python -m train.tables RUN/eval`` writes the markdown tables
again from their JSON files.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import time
from pathlib import Path
from typing import Any

import jax
import numpy as np
import yaml

from sgjax.compilation_cache import add_cache_arguments, cache_from_arguments
from sgjax.evaluation.evaluate import evaluate, lane_results
from sgjax.evaluation.metrics import DEFAULT_CONSTANTS
from sgjax.evaluation.provenance import provenance
from sgjax.evaluation.render import episode_frames, recorded_map, save_gif
from sgjax.evaluation.report import markdown_table, summary_tables, write_all
from sgjax.evaluation.runner import Episodes
from sgjax.evaluation.statistics import (
    ConfigResult,
    Summary,
    paired_difference,
    seed_aggregate,
    t_interval,
)
from sgjax.evaluation.trained import TrainedEvaluation
from sgjax.files import write_atomic
from sgjax.terms.base import ConfigError
from sgjax.version import __version__
from train.algorithm.actor import ActorLayout, ActorWeights, TrainedActor
from train.algorithm.config import (
    EVALUATION_SEED_OFFSET,
    VALIDATION_SEED,
    NetworkConfig,
    TrainConfig,
    apply_overrides,
    config_from_dict,
    load_config,
)
from train.algorithm.trainer import Trainer, seed_keys
from train.algorithm.world_curriculum import LEVEL_STATS
from train.reports.curves import plot_learning_curves
from train.reports.result_schemas import PAIRED, SEED_SPREAD
from train.run import checkpoint
from train.run.loop import Call, train_in_calls
from train.run.phases import Phases
from train.run.sharding import device_mesh, shard_runner
from train.run.socialgym_config import convert, is_socialgym_config, read_socialgym_config, table

COLUMNS = ("steps", "updates", "wall_s", "env_steps_per_s", "agent_steps_per_s", "num_agents",
           "episodes", "team_success", "robot_success", "mean_return", "policy_loss",
           "value_loss", "entropy", "approx_kl", "eval_team_success", "eval_robot_success")


class Logger:
    """Scalars to ``progress.csv`` (:data:`COLUMNS`, then ``extra`` ones) and, when
    tensorboardX is installed and asked for, TensorBoard event files."""

    def __init__(self, out: Path, tensorboard: bool, append: bool,
                 extra: tuple[str, ...] = ()):
        path = out / "progress.csv"
        fresh = not (append and path.is_file())
        self._file = path.open("w" if fresh else "a", newline="")
        self.columns = COLUMNS + tuple(extra)
        self._csv = csv.DictWriter(self._file, fieldnames=self.columns)
        if fresh:
            self._csv.writeheader()
        self._tb = None
        if tensorboard:
            try:
                from tensorboardX import SummaryWriter
            except ImportError:
                print("note: tensorboardX is not installed (pip install -e '.[train]'); "
                      "logging to progress.csv only")
            else:
                self._tb = SummaryWriter(str(out / "tb"))

    def log(self, row: dict[str, Any]) -> None:
        self._csv.writerow({k: row.get(k, "") for k in self.columns})
        self._file.flush()
        if self._tb is not None:
            for name, value in row.items():
                if name != "steps" and isinstance(value, int | float) and math.isfinite(value):
                    self._tb.add_scalar(f"train/{name}", value, int(row["steps"]))
            self._tb.flush()

    def close(self) -> None:
        self._file.close()
        if self._tb is not None:
            self._tb.close()


class Progress:
    """A tqdm bar over environment steps (a plain line per chunk without tqdm)."""

    def __init__(self, total: int, initial: int, enabled: bool):
        self._bar = None
        if enabled:
            try:
                from tqdm import tqdm
            except ImportError:
                pass
            else:
                self._bar = tqdm(total=total, initial=initial, unit="step", unit_scale=True,
                                 dynamic_ncols=True)
        self._total = total

    def update(self, done: int, advanced: int, text: str) -> None:
        if self._bar is not None:
            self._bar.update(advanced)
            self._bar.set_postfix_str(text)
        else:
            print(f"step {done:>10,}/{self._total:,}  {text}", flush=True)

    def write(self, text: str) -> None:
        if self._bar is not None:
            self._bar.write(text)
        else:
            print(text, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


def _updates_per_chunk(config: TrainConfig) -> int:
    a, e, lg = config.algorithm, config.evaluation, config.logging
    interval = min(e.every, lg.checkpoint_every, max(a.total_steps // 20, 1))
    return max(1, min(a.num_updates, interval // a.steps_per_update))


class PeriodicWork:
    """What ``python -m train`` does between training calls: the progress row and bar, the
    periodic evaluation on the validation episodes (every seed at once,
    :class:`sgjax.evaluation.trained.TrainedEvaluation` compiled once for every robot count of
    the curriculum) with the best checkpoint, and the latest checkpoint."""

    def __init__(self, config: TrainConfig, trainer: Trainer, out: Path, meta: dict,
                 resume: bool, phases: Phases):
        self.config, self.trainer, self.meta, self.phases = config, trainer, meta, phases
        self.latest = out / "checkpoints" / "latest.msgpack"
        self.best = out / "checkpoints" / "best.msgpack"
        a, e, lg = config.algorithm, config.evaluation, config.logging
        self.logger = Logger(out, lg.tensorboard, append=resume,
                             extra=LEVEL_STATS if config.levels.active else ())
        self.progress = Progress(a.num_updates * a.steps_per_update, meta["steps"],
                                 lg.progress)
        self.next_eval = (meta["steps"] // e.every + 1) * e.every
        self.next_save = (meta["steps"] // lg.checkpoint_every + 1) * lg.checkpoint_every
        self.wall = meta["wall_s"]
        self._evaluation: TrainedEvaluation | None = None

    def __call__(self, call: Call) -> None:
        config, meta, a = self.config, self.meta, self.config.algorithm
        logs = jax.device_get(call.logs)
        self.wall += call.seconds
        meta["updates"] = call.done
        advanced = call.count * a.steps_per_update * config.num_seeds
        meta["steps"] = int(np.max(logs["steps"]))
        row = _row(logs, meta, self.wall, advanced / call.seconds, self.trainer)
        last = meta["updates"] >= a.num_updates
        if meta["steps"] >= self.next_eval or last:
            self.next_eval += config.evaluation.every
            with self.phases.timing("periodic evaluation"):
                self.evaluate(call.runner, int(np.max(logs["num_agents"])), row)
        self.logger.log(row)
        self.progress.update(meta["steps"], advanced // config.num_seeds,
                             f"{row['env_steps_per_s']:,.0f} env-steps/s, "
                             f"{row['agent_steps_per_s']:,.0f} agent-steps/s, success "
                             f"{row['team_success']:.2f} team / {row['robot_success']:.2f} robot")
        if meta["steps"] >= self.next_save or last:
            self.next_save += config.logging.checkpoint_every
            meta["wall_s"] = self.wall
            checkpoint.save(self.latest, config, call.runner, meta, self.trainer.actor)

    def evaluate(self, runner: Any, count: int, row: dict) -> None:
        """Every seed on the validation episodes with ``count`` robots; the row's evaluation
        columns, and the best checkpoint when the mean team success is the best yet."""
        config, meta = self.config, self.meta
        e, scenario = config.evaluation, config.env.scenarios[0]
        if self._evaluation is None:
            counts = sorted({n for _, n in config.env.curriculum})
            self._evaluation = TrainedEvaluation(
                self.trainer.trained_actor, scenario, counts, e.episodes, config.env.options,
                max_agents=self.trainer.slots, modes=e.deterministic)
        values, _ = jax.device_get(self._evaluation.lanes(
            ActorWeights.of(runner), jax.random.PRNGKey(VALIDATION_SEED), count))
        team = np.mean(values["team_success"], axis=1)
        robot = np.nanmean(values["success"], axis=1)
        row["eval_team_success"], row["eval_robot_success"] = float(np.mean(team)), float(
            np.mean(robot))
        self.progress.write(f"step {meta['steps']:,}: evaluation ({e.episodes} episodes, "
                            f"{count} robots, {scenario}) team success {np.mean(team):.3f}, "
                            f"robot success {np.mean(robot):.3f}")
        if np.mean(team) > meta["best_success"]:
            meta["best_success"], meta["best_seed"] = float(np.mean(team)), int(np.argmax(team))
            meta["wall_s"] = self.wall
            checkpoint.save(self.best, config, runner, meta, self.trainer.actor)

    def close(self) -> None:
        self.progress.close()
        self.logger.close()


def _start(trainer: Trainer, latest: Path, resume: bool) -> tuple[Any, dict[str, Any]]:
    """Fresh lanes of every seed, or the run in ``latest`` with ``resume``; spread over the
    devices when there are several."""
    meta = {"updates": 0, "steps": 0, "best_success": -1.0, "best_seed": 0, "wall_s": 0.0}
    if resume:
        if not latest.is_file():
            raise ConfigError(f"--resume: no checkpoint at {latest}")
        runner, meta = checkpoint.restore(latest, trainer)
        print(f"resumed from {latest} at step {meta['steps']:,} (update {meta['updates']})")
    else:
        runner = jax.jit(jax.vmap(trainer.init))(seed_keys(trainer.config))
    devices = jax.devices()
    if len(devices) > 1:
        runner = shard_runner(runner, device_mesh(devices), trainer.num_envs)
    return runner, meta


def _announce(config: TrainConfig, trainer: Trainer) -> None:
    a, devices = config.algorithm, jax.devices()
    print(f"sgjax {__version__}, jax {jax.__version__} on {len(devices)} "
          f"{devices[0].platform} device(s): {a.name.upper()} on {', '.join(config.env.scenarios)},"
          f" robots {config.env.curriculum} in {trainer.slots} slots, {trainer.num_envs} envs, "
          f"{a.total_steps:,} env steps, {config.num_seeds} seed(s), network "
          f"{config.network.kind}/{config.network.others_encoder}, "
          f"{config.env.action_mode} actions")


def train(config: TrainConfig, out: Path, resume: bool = False) -> dict[str, Any]:
    """Run the whole command; returns the final summary (also printed), with where its time
    went under ``"seconds"`` (also printed last)."""
    phases = Phases("compile", "train", "periodic evaluation")
    a = config.algorithm
    out.mkdir(parents=True, exist_ok=True)
    trainer = Trainer(config)
    _announce(config, trainer)
    (out / "config.yaml").write_text(yaml.safe_dump(config.to_dict(), sort_keys=False))
    runner, meta = _start(trainer, out / "checkpoints" / "latest.msgpack", resume)
    per_call = _updates_per_chunk(config)
    _, compile_s = trainer.compiled_chunk_lanes(per_call, runner, donate=True)
    phases.add("compile", compile_s)
    print(f"compiled {per_call} updates ({per_call * a.steps_per_update:,} env steps) per "
          f"call in {compile_s:.1f} s")
    work = PeriodicWork(config, trainer, out, meta, resume, phases)
    train_in_calls(trainer, runner, per_call, a.num_updates, done=meta["updates"],
                   donate=True, phases=phases, after_call=work)
    work.close()
    print(f"wrote {plot_learning_curves([out], out / 'learning_curve.png')}")
    print(f"trained {meta['steps']:,} env steps in {work.wall:.0f} s "
          f"({meta['steps'] * trainer.slots / max(work.wall, 1e-9):,.0f} agent-steps/s, "
          f"periodic evaluation apart); best evaluation team success "
          f"{meta['best_success']:.3f} -> {work.best}; the final evaluation judges the "
          f"{config.evaluation.checkpoint} weights (evaluation.checkpoint)")
    phases.add("start-up, logs and checkpoints", phases.elapsed() - sum(phases.seconds.values()))
    summary = final_evaluation(config, out, checkpoint.judged_checkpoint(out, config))
    for name, value in summary["seconds"].items():
        phases.add(name, value)
    print(phases.line(" (each phase includes its compiles)"))
    made = provenance(config.to_dict(), seeds=run_seeds(config),
                      episodes_per_cell=config.evaluation.episodes,
                      seconds={**phases.seconds, "total": phases.elapsed()})
    write_atomic(out / "provenance.json", json.dumps(made, indent=1) + "\n")
    return {**summary, "seconds": phases.seconds}


def _row(logs: dict, meta: dict, wall: float, env_rate: float, trainer: Trainer) -> dict:
    episodes = float(np.sum(logs["episodes"]))
    robots = float(np.sum(logs["robots"]))
    count = float(np.mean(logs["num_agents"]))
    return {
        "steps": meta["steps"], "updates": meta["updates"], "wall_s": wall,
        "env_steps_per_s": env_rate, "agent_steps_per_s": env_rate * count,
        "num_agents": count, "episodes": episodes,
        "team_success": float(np.sum(logs["team_successes"])) / max(episodes, 1.0),
        "robot_success": float(np.sum(logs["robot_successes"])) / max(robots, 1.0),
        "mean_return": float(np.sum(logs["return_sum"])) / max(robots, 1.0),
        **{k: float(np.mean(logs[k])) for k in ("policy_loss", "value_loss", "entropy",
                                                "approx_kl")},
        **{k: float(np.mean(logs[k])) for k in LEVEL_STATS if k in logs},
    }


def final_evaluation(config: TrainConfig, out: Path, path: Path) -> dict[str, Any]:
    """Evaluate the checkpoint at every evaluation robot count beside the baseline; print the
    tables, write them and a GIF of one evaluated episode.

    Per scenario, the trained policy and the baseline are the lanes of one compiled program
    (:meth:`sgjax.evaluation.trained.TrainedEvaluation.paired`), called once per robot count
    (two programs only where the baseline acts in another environment than the policy, e.g. a
    continuous-action policy beside GO/STOP ``only_local``): the same episodes, keys and results
    as evaluating each policy with :func:`sgjax.evaluation.evaluate.evaluate` (seed ``config.seed +
    EVALUATION_SEED_OFFSET``, no training lane's). The
    weights are an argument of the program, so the next run of the job finds it in the
    persistent compilation cache, however its training went. The GIF is episode 0
    of the trained policy at the evaluation count nearest the curriculum's last, recorded while
    it is evaluated (``record_lanes``), not played again. ``seconds``: ``final evaluation``
    (compiling, playing, tables and files) and ``GIF`` (drawing and writing it)."""
    e = config.evaluation
    t0 = time.perf_counter()
    print(f"\nfinal evaluation of {path} ({e.episodes} episodes per configuration)")
    actor = _checkpoint_actor(path)
    seeds = _checkpoint_seeds(path)
    counts = list(e.num_agents)
    shown = min(counts, key=lambda n: (abs(n - config.env.curriculum[-1][1]), n))
    trained, per_seed, baseline, recorded, paired, spread = [], [], [], None, {}, {}
    for i, scenario in enumerate(config.env.scenarios):
        record = shown if e.gif and i == 0 else None
        mine, theirs, episode, paired[scenario], by_seed = _evaluate_scenario(
            config, actor, scenario, record, seeds)
        trained, baseline = trained + mine, baseline + theirs
        per_seed += by_seed.pop("results", [])
        spread[scenario] = by_seed
        recorded = recorded if episode is None else episode
    results = trained + per_seed + baseline
    made = provenance(config.to_dict(), seeds=run_seeds(config),
                      episodes_per_cell=e.episodes)
    write_all(results, out / "eval", DEFAULT_CONSTANTS, made)
    print(summary_tables(results))
    _print_paired(paired, e.baseline, _trained_name(config), e.episodes)
    if any(paired.values()):
        document = paired_document(trained + baseline, paired, _trained_name(config),
                                   e.baseline, e.episodes, made)
        write_atomic(out / "eval" / "paired.json", json.dumps(document, indent=1) + "\n")
        write_atomic(out / "eval" / "paired.md", paired_markdown(document))
    _print_seed_spread(spread, e.baseline, e.episodes)
    if any(spread.values()):
        document = _seed_spread_document(spread, _trained_name(config), e.baseline,
                                         e.episodes, made)
        write_atomic(out / "eval" / "seed_spread.json", json.dumps(document, indent=1) + "\n")
        write_atomic(out / "eval" / "seed_spread.md", seed_spread_markdown(document))
    summary = {(r.policy, r.num_agents, r.scenario): r.metrics["team_success"].mean
               for r in results}
    seconds = {"final evaluation": time.perf_counter() - t0}
    t0 = time.perf_counter()
    count, scenario = config.env.curriculum[-1][1], config.env.scenarios[0]
    mine = summary.get((_trained_name(config), count, scenario))
    base = summary.get((e.baseline, count, scenario))
    if recorded is not None:
        _write_gif(scenario, *recorded, shown, out / "eval" / "episode.gif")
    seconds["GIF"] = time.perf_counter() - t0
    if mine is not None and base is not None:
        print(f"\n{scenario}, {count} robots: team success {mine:.3f} trained vs {base:.3f} "
              f"{e.baseline}")
    return {"trained_team_success": mine, "baseline_team_success": base, "results": results,
            "paired": paired, "seed_spread": spread, "seconds": seconds}


def run_seeds(config: TrainConfig) -> dict[str, list[int]]:
    """The seeds of a run by role: ``training`` (one per lane), ``validation`` (the periodic
    evaluation that picks the best checkpoint: its own key, :data:`VALIDATION_SEED`) and
    ``evaluation`` (the final evaluation: ``seed + EVALUATION_SEED_OFFSET``, never a training
    lane's key; its episodes are never seen by the checkpoint choice)."""
    return {"training": [config.seed + i for i in range(config.num_seeds)],
            "validation": [VALIDATION_SEED],
            "evaluation": [config.seed + EVALUATION_SEED_OFFSET]}


def _print_paired(paired: dict[str, dict[int, Summary]], baseline: str | None, name: str,
                  episodes: int) -> None:
    """The paired differences in team success, trained - baseline, one line per scenario."""
    for scenario, by_count in paired.items():
        if not by_count:
            continue
        cells = ", ".join(f"{n}: {d.mean:+.3f} [{d.ci_low:+.3f}, {d.ci_high:+.3f}]"
                          for n, d in by_count.items())
        print(f"{scenario}: team success {name} - {baseline}, paired over the same {episodes} "
              f"episodes (mean [95% t interval]) by robots: {cells}")


def _print_seed_spread(spread: dict[str, dict[int, dict[str, Any]]], baseline: str | None,
                       episodes: int) -> None:
    """Every training seed's team success on the same episodes, their mean and interquartile
    mean with bootstrap intervals over seeds, and how many seeds beat the baseline (paired
    interval above 0); nothing for a one-seed run."""
    for scenario, by_count in spread.items():
        if not by_count:
            continue
        seeds = len(next(iter(by_count.values()))["seeds"])
        print(f"{scenario}: team success of each of the {seeds} training seeds on the same "
              f"{episodes} episodes (mean and IQM over seeds [95% bootstrap interval])"
              + (f"; seeds whose paired interval against {baseline} is above 0" if baseline
                 else "") + ":")
        for n, cell in by_count.items():
            a = cell["aggregate"]
            line = (f"  {n} robots: seeds {' '.join(f'{v:.2f}' for v in cell['seeds'])}; "
                    f"mean {a['mean']:.3f} [{a['mean_low']:.3f}, {a['mean_high']:.3f}], "
                    f"IQM {a['iqm']:.3f} [{a['iqm_low']:.3f}, {a['iqm_high']:.3f}]")
            if "paired" in cell:
                wins = sum(d.ci_low > 0 for d in cell["paired"])
                line += f"; {wins} of {seeds} above {baseline}"
            print(line)


def paired_document(results: list[ConfigResult], paired: dict[str, dict[int, Summary]],
                    policy: str, baseline: str | None, episodes: int,
                    made: dict[str, Any]) -> dict[str, Any]:
    """``eval/paired.json`` (``sgjax.paired/1``): per scenario and robot count, the team
    success of the evaluated policy and of the baseline on the same ``episodes`` (mean and 95%
    interval, as ``metrics.json`` has them) and their paired difference (mean [95% t interval]
    over the episodes, :func:`sgjax.evaluation.statistics.paired_difference`). ``results``: the
    final evaluation's :class:`sgjax.evaluation.statistics.ConfigResult` of both policies."""
    success = {(r.policy, r.scenario, r.num_agents): r.metrics["team_success"]
               for r in results}
    scenarios = {}
    for scenario, by_count in paired.items():
        if by_count:
            scenarios[scenario] = {str(n): {
                "policy": success[policy, scenario, n].as_dict(),
                "baseline": success[baseline, scenario, n].as_dict(),
                "difference": d.as_dict()} for n, d in by_count.items()}
    return {"schema_version": PAIRED, "provenance": made, "policy": policy,
            "baseline": baseline, "episodes": episodes, "scenarios": scenarios}


def paired_markdown(document: dict[str, Any]) -> str:
    """A ``paired.json`` document as one markdown table per scenario: robot counts as columns;
    rows the policy's and the baseline's team success (mean [95% interval]) and the paired
    difference (mean [95% t interval]). No commit in the text (the provenance holds it): the
    README includes the main job's table."""

    def cell(s: dict[str, Any], sign: str = "") -> str:
        return f"{s['mean']:{sign}.2f} [{s['ci_low']:{sign}.2f}, {s['ci_high']:{sign}.2f}]"

    policy, baseline = document["policy"], document["baseline"]
    p = document["provenance"]
    lines = []
    for scenario, cells in document["scenarios"].items():
        counts = list(cells)
        lines += [f"{scenario}: team success on the same {document['episodes']} episodes per "
                  "robot count, mean [95% interval: Wilson per policy, Student-t over the "
                  f"episodes for the paired difference] (sgjax {p['versions']['sgjax']}, "
                  f"{p['machine']['cpu']}; the commit is in the provenance).", "",
                  *markdown_table(["robots", *counts], [
                      [policy, *(cell(cells[n]["policy"]) for n in counts)],
                      [baseline, *(cell(cells[n]["baseline"]) for n in counts)],
                      [f"{policy} - {baseline}, paired",
                       *(cell(cells[n]["difference"], "+") for n in counts)]]), ""]
    return "\n".join(lines).rstrip("\n") + "\n"


def _seed_spread_document(spread: dict[str, dict[int, dict[str, Any]]], policy: str,
                          baseline: str | None, episodes: int,
                          made: dict[str, Any]) -> dict[str, Any]:
    """``eval/seed_spread.json`` (``sgjax.seed_spread/1``) of :func:`_print_seed_spread`'s
    values."""
    scenarios = {}
    for scenario, by_count in spread.items():
        cells = {}
        for n, cell in by_count.items():
            cells[str(n)] = {"team_success": cell["seeds"], "aggregate": cell["aggregate"]}
            if "paired" in cell:
                cells[str(n)]["paired"] = [d.as_dict() for d in cell["paired"]]
        scenarios[scenario] = cells
    return {"schema_version": SEED_SPREAD, "provenance": made, "policy": policy,
            "baseline": baseline, "episodes": episodes, "scenarios": scenarios}


def seed_spread_markdown(document: dict[str, Any]) -> str:
    """A markdown table of a ``seed_spread.json`` document: per scenario and robot count, each
    seed's team success, the mean and IQM over seeds with their 95% bootstrap intervals, and
    each seed's paired difference against the baseline (mean [95% t interval] over the same
    episodes)."""
    baseline = document["baseline"]
    header = ["Scenario", "Robots", "Team success per seed", "Mean [95% CI]", "IQM [95% CI]"]
    if baseline:
        header += [f"Each seed - {baseline}, paired",
                   f"Mean - {baseline} [95% t over seeds]"]
    rows = []
    for scenario, cells in document["scenarios"].items():
        for count, cell in cells.items():
            a = cell["aggregate"]
            row = [scenario, count, " ".join(f"{v:.3f}" for v in cell["team_success"]),
                   f"{a['mean']:.3f} [{a['mean_low']:.3f}, {a['mean_high']:.3f}]",
                   f"{a['iqm']:.3f} [{a['iqm_low']:.3f}, {a['iqm_high']:.3f}]"]
            if baseline:
                differences = [d["mean"] for d in cell.get("paired", [])]
                row.append("; ".join(f"{d['mean']:+.3f} [{d['ci_low']:+.3f}, {d['ci_high']:+.3f}]"
                                     for d in cell.get("paired", [])) or "n/a")
                row.append(_over_seeds(differences))
            rows.append(row)
    made = document["provenance"]
    commit = (made.get("git") or {}).get("commit") or "unknown"
    lines = [f"{document['policy']}: team success of every training seed on the same "
             f"{document['episodes']} evaluation episodes (sgjax {made['versions']['sgjax']}, "
             f"commit {commit[:7]}, {made['machine']['cpu']}). The last column is the mean over "
             "seeds of each seed's paired difference, with a Student-t interval over the seeds "
             "(the seed is the unit: it holds the training seeds' spread and, within each "
             "seed's mean, the episodes').", "",
             *markdown_table(header, rows)]
    return "\n".join(lines) + "\n"


def _over_seeds(differences: list[float]) -> str:
    """``mean [low, high]`` of per-seed paired differences with a 95% Student-t interval over
    the seeds (:func:`sgjax.evaluation.statistics.t_interval`); ``n/a`` under two seeds."""
    if len(differences) < 2:
        return "n/a"
    low, high = t_interval(np.asarray(differences, float))
    return f"{np.mean(differences):+.3f} [{low:+.3f}, {high:+.3f}]"


def _trained_name(config: TrainConfig) -> str:
    return f"trained ({config.algorithm.name})"


def _checkpoint_seeds(path: Path) -> list[tuple[int, ActorWeights, bool]]:
    """Every seed's acting weights of a checkpoint, ``(seed index, weights, best)``; ``best``
    marks the seed :func:`_checkpoint_actor` takes."""
    _, meta, raw = checkpoint.read(path)
    weights = checkpoint.stored_weights(raw)
    count = int(np.shape(weights.obs_stats.mean)[0])
    best = int(meta.get("best_seed", 0))
    return [(i, weights.seed(i), i == best) for i in range(count)]


def _checkpoint_actor(path: Path) -> tuple[NetworkConfig, ActorLayout, ActorWeights]:
    """The acting network, layout and weights (the best seed) of a checkpoint: what
    :func:`train.run.checkpoint.load_checkpoint_policy` builds its policy from, with the weights
    kept apart so that they are an argument of the evaluation program."""
    saved, meta, raw = checkpoint.read(path)
    layout = checkpoint.actor_layout(path, saved, meta, raw)
    weights = checkpoint.stored_weights(raw).seed(int(meta.get("best_seed", 0)))
    return saved.network, layout, weights


def _evaluate_scenario(config: TrainConfig, actor: tuple, scenario: str,
                       record_count: int | None,
                       seeds: list[tuple[int, ActorWeights, bool]] | None = None
                       ) -> tuple[list, list, Any, dict, dict]:
    """The trained policy's and the baseline's results on one scenario at every evaluation
    count: one program, both policies its lanes, called once per count (each count stops with
    its own slowest episode, where every count as lanes of one call would wait for the slowest
    of all). With ``record_count`` (a robot count) also the trained policy's episode 0 at that
    count as ``(states [T + 1, ...], length in steps, params)`` (else None). Last, ``{count:
    Summary}``: the paired difference trained - baseline in team success over the episodes
    both played (:func:`sgjax.evaluation.statistics.paired_difference`; empty without a
    baseline in the same environment).

    With ``seeds`` (every seed's weights, :func:`_checkpoint_seeds`) of more than one seed,
    each seed plays the same episodes through the same program (the weights are its
    argument), and the fifth return is ``{count: {"seeds": [S] team success, "aggregate":
    seed_aggregate(...), "paired": [S] Summary (each seed - baseline, when together)},
    "results": [ConfigResult of each seed, policy "<trained> seed <i>"]}`` (empty for one
    seed)."""
    e, (network, layout, weights) = config.evaluation, actor
    counts, seed = list(e.num_agents), config.seed + EVALUATION_SEED_OFFSET
    options = config.env.options
    go_stop = options.replace(action_mode="go_stop")
    together = e.baseline is not None and go_stop == options  # one environment
    names = [_trained_name(config)] + ([e.baseline] if together else [])
    evaluation = TrainedEvaluation(
        TrainedActor(network, layout), scenario, counts, e.episodes, options,
        modes=e.deterministic,
        baselines=names[1:], record=record_count is not None)
    params = evaluation.params[counts[0]]
    mine, theirs, recorded, paired, spread = [], [], None, {}, {}
    many = seeds is not None and len(seeds) > 1
    for n in counts:
        t0 = time.perf_counter()
        (values, _, states, _), compile_s = evaluation.paired(weights, jax.random.key(seed), n)
        values, states = jax.device_get((values, states))
        batch = Episodes(values={k: np.asarray(v) for k, v in values.items()}, robot={},
                         compile_seconds=compile_s,
                         run_seconds=time.perf_counter() - t0 - compile_s)
        results = lane_results(scenario, names, [n], seed, params, batch, options.to_dict())
        mine, theirs = mine + results[:1], theirs + results[1:]
        if together:  # [policy, episode]: the same episodes, common random numbers
            paired[n] = paired_difference(*batch.values["team_success"][:2])
        if many:
            spread[n] = _seed_cell(evaluation, seeds, seed, n, scenario, names, params,
                                   batch if together else None, batch)
            spread.setdefault("results", [])
            spread["results"] += spread[n].pop("results")
        if n == record_count:
            recorded = (jax.tree.map(lambda leaf: leaf[:, 0], states),
                        int(batch.values["episode_length"][0, 0]), evaluation.params[n])
    if e.baseline is not None and not together:
        theirs = evaluate([scenario], [e.baseline], num_agents=counts, episodes=e.episodes,
                          seed=seed, options=go_stop, log=None)
    return mine, theirs, recorded, paired, spread


def _seed_cell(evaluation: TrainedEvaluation, seeds: list[tuple[int, ActorWeights, bool]],
               key_seed: int, count: int, scenario: str, names: list[str], params: Any,
               together: Episodes | None, first: Episodes) -> dict[str, Any]:
    """One robot count of :func:`_evaluate_scenario`'s seed spread: every seed's episodes
    (key ``key_seed``, so the same episodes as the best seed's and the baseline's; the best
    seed is ``first``'s trained lane, not played again), its
    results, the aggregate over seeds and, with ``together`` (the baseline's batch from the
    same program), each seed's paired difference against the baseline."""
    per_seed, results, differences = [], [], []
    for index, weights, best in seeds:
        if best:  # played already: ``first``
            values = {k: np.asarray(v)[:1] for k, v in first.values.items()}
            batch = Episodes(values=values, robot={}, compile_seconds=0.0,
                             run_seconds=first.run_seconds)
        else:
            t0 = time.perf_counter()
            (values, *_), compile_s = evaluation.paired(weights, jax.random.key(key_seed),
                                                          count)
            values = {k: np.asarray(v)[:1] for k, v in jax.device_get(values).items()}
            batch = Episodes(values=values, robot={}, compile_seconds=compile_s,
                             run_seconds=time.perf_counter() - t0 - compile_s)
        results += lane_results(scenario, [f"{names[0]} seed {index}"], [count], key_seed,
                                params, batch, evaluation.options.to_dict())
        success = values["team_success"][0]
        per_seed.append(float(np.mean(success)))
        if together is not None:
            differences.append(paired_difference(success, together.values["team_success"][1]))
    cell = {"seeds": per_seed, "aggregate": seed_aggregate(np.asarray(per_seed)),
            "results": results}
    if together is not None:
        cell["paired"] = differences
    return cell


def _write_gif(scenario: str, states: Any, length: int, params: Any, count: int,
               path: Path) -> None:
    """Draw a recorded evaluation episode (``states [T + 1, ...]``, ``length`` steps, ``count``
    robots) into ``path``."""
    frames, stride = episode_frames(recorded_map(scenario, states), states, params, length,
                                    title=f"{scenario} / trained, {count} robots",
                                    width_px=400)
    gif = save_gif(frames, path, fps=max(1, round(1 / (float(params.dt) * stride))))
    print(f"wrote {gif}")


def _socialgym_config(path: str, overrides: list[str]) -> TrainConfig | None:
    """A SocialGym 2.0 experiment config (JSON), converted with its key table printed; None for
    an sgjax config."""
    if not path.endswith(".json") or not Path(path).is_file():
        return None
    data = read_socialgym_config(path)
    if not is_socialgym_config(data):
        return None
    converted, rows = convert(data, path)
    print(f"{path}: a SocialGym 2.0 experiment config, read as (python -m "
          f"train.run.socialgym_config {path} --out <file.yaml> writes it):\n{table(rows)}\n")
    return config_from_dict(apply_overrides(converted, overrides), f"{path} (converted)")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m train", description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", required=True,
                        help="YAML file (train/configs/*.yaml), or a SocialGym 2.0 experiment "
                             "config (.json)")
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="override one config key (repeatable), e.g. algorithm.total_steps=1e6")
    parser.add_argument("--out", default=None, help="run folder (default: logging.out)")
    parser.add_argument("--resume", action="store_true",
                        help="continue from <out>/checkpoints/latest.msgpack")
    add_cache_arguments(parser)
    args = parser.parse_args(argv)
    try:
        cache_from_arguments(args)
        config = _socialgym_config(args.config, args.set) or load_config(args.config, args.set)
        train(config, Path(args.out or config.logging.out), resume=args.resume)
    except (ConfigError, ValueError) as err:
        raise SystemExit(f"train: {err}") from err


if __name__ == "__main__":
    main()
