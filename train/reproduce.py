"""Reproduce the SocialGym 2.0 paper's benchmark: its baselines on the five mini-games, several
seeds each, evaluated at 3, 4, 5, 7 and 10 robots; writes its two tables with 95% intervals
over seeds.

    python -m train.reproduce --seeds 3 --total-steps 2000000 --out runs/reproduce

Baselines (the paper's section V): ``cadrl`` (the CADRL reward preset, MLP), ``cadrl_lstm``
(the same as LSTM-PPO, the paper's CADRL(L): sb3-contrib's RecurrentPPO with
``MlpLstmPolicy``, an LSTM of 256 over time in the actor and in the critic), ``any_order`` and
``enforced_order`` (its conflict-zone rewards with the zone observations), and ``only_local``
(always GO, not trained); ``--baselines`` may add the classical controllers ``orca``, ``dwa``
and ``social_force`` (``sgjax.evaluation.controllers``, continuous actions, not trained) as extra
rows
in the same world. Training follows the paper's setting where sgjax can: PPO, GO/STOP
over the local planner, observation and reward normalisation, 3 robots, then 3 or 4 drawn per
episode from a tenth of the steps on (the paper's "trained with up to 4 agents"; a policy that
met only 4 robots for most of its training forgets 3: open/cadrl scored 0.00 at 3 robots and
1.00 at 4 without the draw). Each seed is one lane of one jitted run
(``train.run.loop.train_in_calls``).

Two profiles (``--profile``):

* ``sgjax`` (the default): the settings above, at sgjax's 10 Hz step (dt 0.1 s), 75 s
  episodes, 256 environments per update, evaluation with sampled actions;
* ``socialgym``: each baseline as SocialGym 2.0 itself ran it: its ``config_run.py`` defaults
  for the baseline's run type (``SACADRL`` for CADRL, the same on RecurrentPPO for CADRL(L),
  ``AO``, ``EO``) with the settings of the paper's Listing 1, converted by
  :mod:`train.run.socialgym_config` (40 Hz steps, 3200-step episodes, its observation and reward
  sets, the stuck ender with its -100000 penalty, SB3 PPO's hyperparameters and network with
  n_steps 4096, 16 environments), the paper's curriculum (35 episodes of 3 robots, 35 of 4,
  then 5), 250,000 environment steps by default, greedy evaluation. 4x the simulated steps
  per second of an episode and SB3's minibatches of 64: far slower per environment step than
  ``sgjax``.

Outputs in ``--out``: ``metrics_table.md`` (the paper's Table 3: length, collisions, stop time,
max delta-V and team success per scenario and baseline, at ``--table-robots``),
``success_table.md`` (its Table 4: team success % by robot count, with the average),
``paper_comparison.md`` (ours beside the paper's Table 4), ``comparison_table.md`` (each
trained baseline against Only Local, paired over the shared episodes, with seed aggregates),
``baseline_comparison.md`` (each other trained baseline against CADRL, paired seed by seed),
``play_modes.md`` (trained policies playing greedily and sampling), ``results.json`` (every
seed's value of every metric, per configuration, schema ``sgjax.reproduce/1``;
``--from-results`` writes the tables again from it) and ``marl_eval.json`` (the same results
for marl-eval, :mod:`train.reports.marl_eval`).
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import jax
import numpy as np

from sgjax.compilation_cache import add_cache_arguments, cache_from_arguments
from sgjax.environment.options import MakeOptions
from sgjax.environment.presets import REWARD_PRESETS
from sgjax.evaluation.evaluate import params_by_count
from sgjax.evaluation.policies import load_policy, policy_options
from sgjax.evaluation.protocols import MINI_GAMES, PAPER
from sgjax.evaluation.provenance import provenance
from sgjax.evaluation.report import format_points, format_summary, markdown_table
from sgjax.evaluation.runner import EpisodeRunner
from sgjax.evaluation.statistics import (
    Summary,
    paired_difference,
    paired_over_seeds_and_episodes,
    probability_of_improvement,
    seed_aggregate,
    summarize,
)
from sgjax.evaluation.trained import TrainedEvaluation
from sgjax.files import write_atomic
from train.algorithm.actor import ActorWeights
from train.algorithm.config import EVALUATION_SEED_OFFSET, TrainConfig, config_from_dict
from train.algorithm.trainer import Trainer, seed_keys
from train.reports.across_cells import across_cells_table, plot_performance_profiles
from train.reports.marl_eval import to_marl_eval
from train.reports.result_schemas import REPRODUCE
from train.run.loop import equal_calls, train_in_calls
from train.run.multiprocess import Processes, add_arguments, gather_lanes, initialize, lane_share
from train.run.partial import (
    SAVES_PER_RUN,
    PartialFile,
    PartialValues,
    shaped_like,
    weights_hash,
)
from train.run.phases import Phases

BASELINES = {
    "cadrl": {"env": {"preset": "cadrl"}, "network": {}},
    # the paper's CADRL(L): LSTM-PPO (RecurrentPPO's MlpLstmPolicy: an LSTM of 256 over time
    # in the actor and in the critic), CADRL otherwise, so the pair varies the memory alone
    "cadrl_lstm": {"env": {"preset": "cadrl"},
                   "network": {"kind": "lstm", "recurrent_size": 256}},
    "any_order": {"env": {"preset": "any_order"}, "network": {}},
    "enforced_order": {"env": {"preset": "enforced_order"}, "network": {}},
    "only_local": None,
    # Classical baselines (sgjax.evaluation.controllers), not trained: extra rows, not in the paper.
    "orca": None,
    "dwa": None,
    "social_force": None,
}
PAPER_BASELINES = ("cadrl", "cadrl_lstm", "any_order", "enforced_order", "only_local")
TABLE_METRICS = (("episode_length", "Avg. length (steps)"), ("collisions", "Coll. rate"),
                 ("stop_time", "Stop time (s)"), ("velocity_change_max", "Max dV (m/s)"),
                 ("team_success", "Team success"))


def baseline_config(name: str, scenario: str, seeds: int, total_steps: int, num_envs: int,
                    seed: int, time_limit: float = 75.0) -> Any:
    spec = BASELINES[name]
    return config_from_dict({
        "seed": seed, "num_seeds": seeds,
        "env": {"scenarios": [scenario], "curriculum": [[0, 3], [total_steps // 10, 4]],
                "min_agents": 3, "time_limit": time_limit, **spec["env"]},
        "algorithm": {"total_steps": total_steps, "num_envs": num_envs},
        "network": spec["network"],
    }, f"reproduce:{name}")


PROFILES = ("sgjax", "socialgym")
# The socialgym profile: each trained baseline as a SocialGym 2.0 run (config_run.py keys).
SOCIALGYM_RUNS: dict[str, dict[str, Any]] = {
    "cadrl": {"run_type": "SACADRL"},
    "cadrl_lstm": {"run_type": "SACADRL", "policy_algo_sb3_contrib": True,
                   "policy_algo_name": "RecurrentPPO", "policy_name": "MlpLstmPolicy"},
    "any_order": {"run_type": "AO"},
    "enforced_order": {"run_type": "EO"},
}
# The paper's Listing 1 (its door/AO experiment) without the keys each run sets: the curriculum
# (35 episodes of 3 robots, 35 of 4, then 5), SB3 PPO with n_steps 4096, velocities and
# headings observed, the stuck ender's constant -100000 to the robots that had not finished.
LISTING_1: dict[str, Any] = {
    "num_agents": [[0, 3], [35, 4], [70, 5]], "intermediate_eval_trials": -1,
    "policy_algo_kwargs": {"n_steps": 4096}, "monitor": False,
    "other_velocities_obs": True, "agent_velocity_obs": True,
    "agent_velocity_ignore_theta": False, "other_velocities_ignore_theta": False,
    "other_poses_ignore_theta": False, "agent_pose_ignore_theta": False,
    "entropy_constant_penalty": -100000,
    "entropy_constant_penalty_only_those_that_did_not_finish": True,
}
LISTING_1_STEPS = 250_000  # its train_length (x 5 robots = the paper's 1.25M agent steps)


def socialgym_baseline_config(name: str, scenario: str, seeds: int, total_steps: int,
                              seed: int, counts: Sequence[int], episodes: int,
                              time_limit: float | None = None) -> TrainConfig:
    """Baseline ``name`` on ``scenario`` as SocialGym 2.0 ran it (the ``socialgym`` profile;
    see the module doc): its config converted by :func:`train.run.socialgym_config.convert`."""
    from train.run.socialgym_config import SCENARIOS, convert

    names = {ours: theirs for theirs, ours in SCENARIOS.items()}
    if scenario not in names:
        raise ValueError(f"--profile socialgym runs SocialGym's mini-games "
                         f"({', '.join(names)}); {scenario!r} is not one")
    data, _ = convert({**LISTING_1, "experiment_names": names[scenario],
                       "train_length": total_steps, "eval_num_agents": list(counts),
                       "ending_eval_trials": episodes, "eval_frequency": 0,
                       **SOCIALGYM_RUNS[name]}, f"reproduce --profile socialgym ({name})")
    data["seed"], data["num_seeds"] = seed, seeds
    if time_limit is not None:
        data["env"]["time_limit"] = time_limit
    return config_from_dict(data, f"reproduce:{name} (socialgym profile)")


def only_local_options(profile: str, time_limit: float | None) -> MakeOptions:
    """``sgjax.make`` options of the untrained Only Local baseline under ``profile``: the
    trained baselines' world (step, time limit, robots, arrived robots) and their enders, so the
    stuck ender cuts Only Local's episodes short exactly as it cuts theirs (their observations
    and rewards do not move a policy that always says GO)."""
    if profile == "sgjax":
        limit = 75.0 if time_limit is None else time_limit
        trained = baseline_config("cadrl", "open", 1, 1, 1, 0, limit).env.options
    else:
        trained = socialgym_baseline_config("cadrl", "open", 1, 1, 0, [3], 1,
                                            time_limit).env.options
    enders = trained.terms.enders
    if enders is None and isinstance(trained.terms.rewards, str):
        enders = REWARD_PRESETS[trained.terms.rewards]["enders"]  # the preset's
    return MakeOptions.from_keywords(
        "only_local", dt=trained.physics.dt, time_limit=trained.physics.time_limit,
        robots=trained.robots.robots, arrived=trained.robots.arrived, enders=enders)


def partial_path(out: Path, scenario: str, name: str) -> Path:
    """Where a cell keeps its lanes while they train (deleted once its results are written)."""
    return out / "partial" / f"{scenario}-{name}.msgpack"


def evaluation_path(out: Path, scenario: str, name: str) -> Path:
    """Where a cell keeps each robot count's evaluation as it is played (deleted once its
    results are written)."""
    return out / "partial" / f"{scenario}-{name}.evaluation.json"


def train_baseline(config: Any, partial: Path | None = None, resume: bool = False
                   ) -> tuple[Trainer, Any, float, float]:
    """Train every seed of ``config`` at once, as lanes
    (:func:`train.run.loop.train_in_calls`), in about ten calls of equal numbers of updates;
    returns the trainer, the seed-batched runner, the seconds spent compiling and the seconds
    spent training.

    With ``partial`` (a checkpoint path, :class:`train.run.partial.PartialFile`) the runner is
    saved there about ten times and a ``resume`` run finding the file continues from it (the
    same config, or an error naming the file), so a cell killed midway loses at most a tenth
    of its work (a run without ``resume`` deletes a file it finds); the caller deletes the file
    once the cell is written."""
    trainer = Trainer(config)
    updates = config.algorithm.num_updates
    phases = Phases("compile", "train")
    start = jax.jit(jax.vmap(trainer.init))
    keys = seed_keys(config)
    file = PartialFile(partial, config, "cell", resume=resume, saves=SAVES_PER_RUN)
    loaded = file.load(shaped_like(jax.eval_shape(start, keys)))
    if loaded is None:
        with phases.timing("compile"):
            runner, done = start(keys), 0
    else:
        runner, done = loaded
        print(f"    resuming {partial} at update {done} of {updates}", flush=True)
    per_call = equal_calls(updates, SAVES_PER_RUN)
    runner, _ = train_in_calls(
        trainer, runner, per_call, updates, done=done, phases=phases,
        after_call=lambda call: file.save_if_due(call.runner, call.done, per_call, updates))
    return trainer, runner, phases.seconds["compile"], phases.seconds["train"]


def evaluate_seeds(scenario: str, counts: Sequence[int], episodes: int, seed: int,
                   trainer: Trainer | None, runner: Any, options: MakeOptions,
                   policy: str = "only_local", kept: Path | None = None, resume: bool = False
                   ) -> dict[int, dict[str, list[float]]]:
    """``{robots: {metric: [per-seed mean over episodes]}}`` (one seed for an untrained
    ``policy``, used when ``trainer`` is None) in the ``sgjax.make`` ``options`` (for an
    untrained policy, with what it needs on top: continuous actions for the velocity
    controllers). One compilation serves every count: the environment has ``max(counts)``
    slots and each count is a params value; the seeds are lanes of it
    (:class:`sgjax.evaluation.trained.TrainedEvaluation`), playing greedily and sampling in one
    program (the profile's mode first: its values fill the tables).

    With ``kept`` (a JSON file, :class:`train.run.partial.PartialValues`) each count's values
    are kept as soon as they are played, for the weights evaluated (their hash), and a
    ``resume`` run plays only the counts not kept: a cell's evaluation at SocialGym's 40 Hz
    takes hours, and a run killed in it loses at most one count."""
    key = jax.random.PRNGKey(seed + EVALUATION_SEED_OFFSET)
    weights = None if trainer is None else ActorWeights.of(runner)
    identity = {"policy": policy if trainer is None else weights_hash(weights),
                "episodes": episodes, "seed": seed}
    done = PartialValues(kept, identity, resume)
    out: dict[int, dict[str, list[float]]] = {}
    play = _untrained_play(scenario, counts, episodes, options, policy, key) \
        if trainer is None else _trained_play(scenario, counts, episodes, options, trainer,
                                              weights, key)
    for n in counts:
        values = done.get(str(n))
        if values is None:
            values = play(n)
            done.put(str(n), values)
        out[n] = values
    return out


def _untrained_play(scenario: str, counts: Sequence[int], episodes: int,
                    options: MakeOptions, policy: str, key: Any
                    ) -> Callable[[int], dict[str, list[float]]]:
    """``play(n)``: the untrained ``policy``'s :func:`seed_values` (one seed) at ``n`` robots;
    compiled at the first call."""
    options = options.replace(**policy_options(policy).keywords(changed_only=True))
    env, by_count = params_by_count(scenario, counts, options=options)
    first = by_count[counts[0]]
    run = EpisodeRunner(env, load_policy(policy, env), episodes, int(first.max_steps)).run
    return lambda n: seed_values({name: v[None] for name, v in
                                  jax.device_get(run(key, by_count[n])[0]).items()})


def _trained_play(scenario: str, counts: Sequence[int], episodes: int, options: MakeOptions,
                  trainer: Trainer, weights: Any, key: Any
                  ) -> Callable[[int], dict[str, list[float]]]:
    """``play(n)``: every seed's :func:`seed_values` at ``n`` robots in the profile's play
    mode, with both modes' team success per seed (:data:`PLAY_MODE_KEYS`)."""
    greedy = trainer.config.evaluation.deterministic
    evaluation = TrainedEvaluation(trainer.trained_actor, scenario, counts, episodes, options,
                                   modes=(greedy, not greedy))

    def play(n: int) -> dict[str, list[float]]:
        both, _ = jax.device_get(evaluation.lanes(weights, key, n))
        values = seed_values({name: v[0] for name, v in both.items()})
        modes = dict(zip((greedy, not greedy), both["team_success"], strict=True))
        for mode, key_name in ((True, PLAY_MODE_KEYS[0]), (False, PLAY_MODE_KEYS[1])):
            values[key_name] = np.nanmean(np.asarray(modes[mode], float), axis=1).tolist()
        return values

    return play


def seed_values(values: dict[str, np.ndarray]) -> dict[str, list[float]]:
    """Every metric's mean over the episodes of each seed (``values {metric: [S, E]}``; NaN
    where a seed has no finite value), and the per-episode team success (:data:`EPISODES_KEY`,
    ``[S, E]``)."""
    out = {name: [float(np.nanmean(row)) if np.isfinite(row).any() else math.nan
                  for row in v] for name, v in values.items()}
    out[EPISODES_KEY] = np.asarray(values["team_success"], float).tolist()
    return out


# The paper's Table 4 (team success %, 25 trials, one seed): scenario -> baseline -> the
# counts 3, 4, 5, 7, 10 and the average as printed.
PAPER_TABLE_4: dict[str, dict[str, tuple[int, ...]]] = {
    "open": {"cadrl": (32, 28, 8, 0, 0, 7), "cadrl_lstm": (60, 44, 52, 36, 4, 39),
             "enforced_order": (24, 12, 12, 0, 0, 10), "any_order": (16, 12, 8, 8, 0, 9),
             "only_local": (56, 32, 36, 16, 0, 28)},
    "doorway": {"cadrl": (28, 32, 16, 8, 0, 17), "cadrl_lstm": (8, 0, 4, 12, 16, 8),
                "enforced_order": (64, 44, 28, 8, 4, 30), "any_order": (72, 84, 64, 24, 4, 50),
                "only_local": (48, 4, 0, 0, 0, 10)},
    "hallway": {"cadrl": (24, 24, 12, 4, 0, 13), "cadrl_lstm": (68, 40, 12, 0, 0, 24),
                "enforced_order": (40, 48, 28, 16, 0, 26), "any_order": (44, 28, 16, 0, 0, 18),
                "only_local": (4, 0, 0, 0, 0, 1)},
    "intersection": {"cadrl": (60, 20, 20, 4, 4, 22), "cadrl_lstm": (24, 28, 12, 20, 8, 18),
                     "enforced_order": (80, 56, 44, 28, 0, 42),
                     "any_order": (52, 28, 24, 4, 4, 22), "only_local": (32, 16, 0, 0, 0, 10)},
    "roundabout": {"cadrl": (24, 20, 8, 0, 0, 10), "cadrl_lstm": (40, 8, 0, 8, 0, 11),
                   "enforced_order": (0, 0, 0, 0, 0, 0), "any_order": (16, 20, 12, 0, 4, 10),
                   "only_local": (4, 0, 0, 0, 0, 1)},
}
PAPER_COUNTS = PAPER.num_agents  # the columns of PAPER_TABLE_4


def paper_average_slips(table: Mapping[str, Mapping[str, Sequence[int]]] = PAPER_TABLE_4,
                        tolerance: float = 1.0) -> list[tuple[str, str, int, float]]:
    """The paper's rows whose printed average differs from the mean of their own counts by
    ``tolerance`` points or more (rounding allowed for): ``(scenario, baseline, printed, mean)``.
    There is one: the open map's CADRL prints 7 where its row, 32 28 8 0 0, averages 13.6."""
    slips = []
    for scenario, by_baseline in table.items():
        for baseline, row in by_baseline.items():
            mean = float(np.mean(row[:-1]))
            if abs(mean - row[-1]) >= tolerance:
                slips.append((scenario, baseline, int(row[-1]), mean))
    return slips


def _cell(values: list[float], percent: bool = False) -> str:
    """Mean over seeds ± the half width of its Student-t interval."""
    return format_summary(summarize(np.asarray(values), binary=False), percent)


def on_shared_episodes(results: dict, counts: Sequence[int]) -> dict:
    """``results`` with every untrained baseline's team success (only_local, the classical
    controllers) taken over the episodes its scenario's trained baselines played (the first
    ``E`` of its own: the same keys), so that every row of a scenario's team success is
    measured on the same episodes; cells without per-episode values stay as they are."""
    out = {}
    for scenario, by_baseline in results.items():
        shared = {}
        for n in counts:
            played = [by_count[n][EPISODES_KEY] for b, by_count in by_baseline.items()
                      if BASELINES.get(b) is not None and EPISODES_KEY in by_count.get(n, {})]
            if played:
                shared[n] = np.asarray(played[0], float).shape[1]
        out[scenario] = {}
        for baseline, by_count in by_baseline.items():
            if BASELINES.get(baseline) is not None:
                out[scenario][baseline] = by_count
                continue
            out[scenario][baseline] = {
                n: cell if n not in shared or EPISODES_KEY not in cell else
                {**cell, "team_success": [float(np.nanmean(
                    np.asarray(cell[EPISODES_KEY], float)[0, :shared[n]]))]}
                for n, cell in by_count.items()}
    return out


# The trained baseline the others are compared with: the paper's plain PPO with the CADRL reward.
REFERENCE_BASELINE = "cadrl"
PAIRED_RESAMPLES = 2000  # the two-level bootstrap's resamples per cell against Only Local
PROFILES_PLOT = "performance_profiles.png"  # every baseline's performance profile


def format_tables(results: dict, counts: Sequence[int], table_robots: int, seeds: int
                  ) -> dict[str, str]:
    """Every table as markdown, by file name (``metrics_table.md``, ``success_table.md``,
    ``paper_comparison.md``, ``comparison_table.md``, ``baseline_comparison.md``,
    ``play_modes.md``, ``across_cells.md``)."""
    note = (f"Means over seeds (each seed: the mean over its evaluation episodes) ± the half "
            f"width of the 95% Student-t interval over {seeds} seeds (none for the untrained "
            "baselines: only_local and the classical controllers, whose team success is "
            "taken over the trained baselines' episodes, the first of their own, so that a "
            "scenario's rows share their episodes; their other metrics over all their "
            "episodes).")
    metric_rows, success_rows = [], []
    everything, results = results, on_shared_episodes(results, counts)
    for scenario, by_baseline in results.items():
        for baseline, by_count in by_baseline.items():
            at = by_count.get(table_robots)
            if at is not None:
                metric_rows.append([scenario, baseline,
                                    *(_cell(at[m]) for m, _ in TABLE_METRICS)])
            means = [np.nanmean(by_count[n]["team_success"]) for n in counts]
            success_rows.append([scenario, baseline,
                                 *(_cell(by_count[n]["team_success"], percent=True)
                                   for n in counts), f"{100 * np.mean(means):.0f}"])
    rows = ["# SocialGym 2.0 Table 3, reproduced with sgjax", "", note, "",
            f"Evaluated with {table_robots} robots.", "",
            *markdown_table(["Scenario", "Baseline", *(t for _, t in TABLE_METRICS)],
                            metric_rows)]
    success = ["# SocialGym 2.0 Table 4 (team success %), reproduced with sgjax", "", note, "",
               *markdown_table(["Scenario", "Baseline", *(f"{n}A" for n in counts), "Avg."],
                               success_rows)]
    compare_rows = []
    for scenario, by_baseline in results.items():
        for baseline, by_count in by_baseline.items():
            paper = PAPER_TABLE_4.get(scenario, {}).get(baseline)
            if paper is None or tuple(counts) != PAPER_COUNTS:
                continue
            ours = [f"{100 * np.nanmean(by_count[n]['team_success']):.0f}" for n in counts]
            mean = np.mean([np.nanmean(by_count[n]["team_success"]) for n in counts])
            compare_rows.append([scenario, baseline, *(f"{o} / {t}" for o, t in
                                                       zip(ours, paper, strict=False)),
                                 f"{100 * mean:.0f} / {paper[-1]}"])
    compare = ["# Team success (%), sgjax / the paper's Table 4", "",
               f"sgjax: the mean over {seeds} seeds (each seed: its evaluation episodes); the "
               "paper: one run of 25 trials, as printed.", "",
               *markdown_table(["Scenario", "Baseline", *(f"{n}A" for n in counts), "Avg."],
                               compare_rows)]
    slips = [f"{scenario} {baseline} prints {printed} where its own row averages {mean:.1f}"
             for scenario, baseline, printed, mean in paper_average_slips()
             if baseline in results.get(scenario, {})]
    if compare_rows and slips:
        compare += ["", "The paper's Avg. column is copied as printed; where it disagrees with "
                    "the paper's own row: " + "; ".join(slips) + "."]
    return {"metrics_table.md": "\n".join(rows) + "\n",
            "success_table.md": "\n".join(success) + "\n",
            "paper_comparison.md": "\n".join(compare) + "\n",
            "comparison_table.md": comparison_table(everything, counts, seeds),
            "baseline_comparison.md": baseline_comparison_table(results, counts, seeds),
            "play_modes.md": play_mode_table(results, counts, seeds),
            "across_cells.md": across_cells_table(
                results, counts, ("only_local", REFERENCE_BASELINE),
                "Every baseline over every mini-game and robot count")}


def play_mode_table(results: dict, counts: Sequence[int], seeds: int) -> str:
    """Team success of every trained baseline playing greedily and sampling, with the paired
    difference over seeds (the same seed's weights and evaluation episodes both ways)."""
    rows = []
    for scenario, by_baseline in results.items():
        for baseline, by_count in by_baseline.items():
            for n in counts:
                cell = by_count.get(n, {})
                if not all(k in cell for k in PLAY_MODE_KEYS):
                    continue
                greedy, sampled = (np.asarray(cell[k], float) for k in PLAY_MODE_KEYS)
                d = paired_difference(greedy, sampled)
                interval = ("" if not np.isfinite(d.ci_low) else
                            f" [{100 * d.ci_low:+.0f}, {100 * d.ci_high:+.0f}]")
                rows.append([scenario, baseline, str(n), f"{100 * np.nanmean(greedy):.0f}",
                             f"{100 * np.nanmean(sampled):.0f}",
                             f"{100 * d.mean:+.0f}{interval}"])
    text = ["# Greedy and sampled play (team success %)", "",
            f"The mean over {seeds} training seeds of each seed's team success when its policy "
            "takes its most likely action (greedy) and when it samples; greedy - sampled: "
            "paired over seeds, mean [95% Student-t interval].", "",
            *markdown_table(["Scenario", "Baseline", "Robots", "Greedy", "Sampled",
                             "Greedy - sampled"], rows)]
    return "\n".join(text) + "\n"


def shared_episodes(trained: dict, baseline: dict) -> tuple[np.ndarray, np.ndarray] | None:
    """A trained cell's team success per seed and episode ``[S, E]`` and an untrained
    baseline's on the same episodes ``[E]`` (its first ``E``: episode ``i`` has the same key
    whatever the count), or None where either lacks per-episode values."""
    if EPISODES_KEY not in trained or EPISODES_KEY not in baseline:
        return None
    mine = np.asarray(trained[EPISODES_KEY], float)
    return mine, np.asarray(baseline[EPISODES_KEY], float)[0, :mine.shape[1]]


def _paired_cell(trained: dict, baseline: dict) -> Summary | None:
    """Paired difference in team success, trained - baseline, over the episodes both played,
    resampling training seeds and episodes together
    (:func:`~sgjax.evaluation.statistics.paired_over_seeds_and_episodes`); None without
    per-episode values."""
    pair = shared_episodes(trained, baseline)
    if pair is None:
        return None
    return paired_over_seeds_and_episodes(*pair, resamples=PAIRED_RESAMPLES)


def _excludes_zero(d: Summary | None) -> bool:
    return d is not None and (d.ci_low > 0.0 or d.ci_high < 0.0)


def chance_note(tests: Sequence[Summary | None]) -> str:
    """The multiple-comparison note of a table of paired intervals: how many would exclude 0
    by chance alone at 95% if nothing differed, and how many do."""
    done = [d for d in tests if d is not None]
    if not done:
        return ""
    return (f"{len(done)} paired interval{'s' if len(done) != 1 else ''}: if no baseline "
            "differed, about "
            f"{0.05 * len(done):.0f} would exclude 0 by chance alone at 95%; "
            f"{sum(map(_excludes_zero, done))} do. A claim resting on one cell may be one of "
            "those.")


def _shared_mean(trained: dict, baseline: dict) -> str:
    """The untrained baseline's team success (%) on the trained cell's episodes."""
    pair = shared_episodes(trained, baseline)
    return "n/a" if pair is None else f"{100 * np.nanmean(pair[1]):.0f}"


def comparison_table(results: dict, counts: Sequence[int], seeds: int) -> str:
    """Every trained baseline against only_local, cell by cell: the paired difference in team
    success over the shared episodes, and the seed aggregate (mean and interquartile mean
    with percentile-bootstrap intervals over the training seeds,
    :func:`sgjax.evaluation.statistics.seed_aggregate`). A baseline "beats" only_local in a
    cell where the paired interval excludes 0."""
    rows, tests = [], []
    for scenario, by_baseline in results.items():
        reference = by_baseline.get("only_local")
        for baseline, by_count in by_baseline.items():
            if baseline not in BASELINES or BASELINES[baseline] is None:
                continue  # untrained: only_local and the classical controllers
            for n in counts:
                agg = seed_aggregate(np.asarray(by_count[n]["team_success"], float))
                d = None if reference is None else _paired_cell(by_count[n], reference[n])
                tests.append(d)
                rows.append([scenario, baseline, str(n),
                             "n/a" if reference is None else _shared_mean(by_count[n],
                                                                          reference[n]),
                             "n/a" if d is None else format_points(d.mean, d.ci_low,
                                                                    d.ci_high),
                             f"{100 * agg['mean']:.0f} [{100 * agg['mean_low']:.0f}, "
                             f"{100 * agg['mean_high']:.0f}]",
                             f"{100 * agg['iqm']:.0f} [{100 * agg['iqm_low']:.0f}, "
                             f"{100 * agg['iqm_high']:.0f}]"])
    text = ["# Trained baselines against Only Local (team success, percentage points)", "",
            "Only Local: its team success (%) on the trained baseline's episodes (the same "
            "evaluation keys; Table 4 prints the same). Paired: every seed's team success on "
            "each episode minus Only Local's in that episode, mean [95% two-level bootstrap "
            "interval: training seeds and episodes resampled together, "
            f"{PAIRED_RESAMPLES:,} resamples, so the interval carries the spread of training "
            "seeds as well as of episodes]; an interval above 0 is a win in that cell. Seeds: "
            f"the {seeds} training seeds' own means, mean and interquartile mean [95% "
            "percentile-bootstrap interval over seeds, 2,000 resamples]. n/a: no per-episode "
            "values (a results.json written before they were kept) or no Only Local row.", "",
            *markdown_table(["Scenario", "Baseline", "Robots", "Only Local (%)",
                             "Paired vs only_local", "Mean over seeds", "IQM over seeds"],
                            rows)]
    note = chance_note(tests)
    return "\n".join(text + (["", note] if note else [])) + "\n"




def baseline_comparison_table(results: dict, counts: Sequence[int], seeds: int,
                              reference: str = REFERENCE_BASELINE) -> str:
    """Every other trained baseline against ``reference`` (CADRL), cell by cell, paired seed
    by seed: seed ``i`` of each was trained from the same key ``seed + i`` and played the same
    evaluation episodes, so the difference of their team success (points) is taken per seed,
    mean [95% Student-t interval over seeds], with the probability of improvement (a random
    seed of the baseline above a random seed of the reference, ties half). The paper's
    comparisons between its trained baselines (CADRL(L) against CADRL, the order rewards
    against CADRL) hold in a cell only where the interval excludes 0."""
    rows, tests = [], []
    for scenario, by_baseline in results.items():
        mine = by_baseline.get(reference)
        if mine is None:
            continue
        for baseline, by_count in by_baseline.items():
            if baseline == reference or BASELINES.get(baseline) is None:
                continue  # the reference itself, and untrained rows (in comparison_table.md)
            for n in counts:
                theirs = np.asarray(by_count[n]["team_success"], float)
                ours = np.asarray(mine[n]["team_success"], float)
                d = paired_difference(theirs, ours)
                tests.append(d if np.isfinite(d.ci_low) else None)
                rows.append([scenario, baseline, str(n),
                             f"{100 * np.nanmean(theirs):.0f}", f"{100 * np.nanmean(ours):.0f}",
                             format_points(d.mean, d.ci_low, d.ci_high),
                             f"{probability_of_improvement(theirs, ours):.2f}"])
    text = [f"# Trained baselines against {reference} (team success, percentage points)", "",
            f"Paired seed by seed: seed i of each baseline and of {reference} trained from the "
            "same key and played the same evaluation episodes; the difference of their team "
            f"success, mean [95% Student-t interval over {seeds} seeds] (an interval that "
            "excludes 0 is a difference), and P(improvement): the chance that a random seed of "
            f"the baseline beats a random seed of {reference} (ties half).", "",
            *markdown_table(["Scenario", "Baseline", "Robots", "Baseline (%)",
                             f"{reference} (%)", f"Paired vs {reference}", "P(improvement)"],
                            rows)]
    note = chance_note(tests)
    return "\n".join(text + (["", note] if note else [])) + "\n"


def write_tables(results: dict, counts: Sequence[int], table_robots: int, seeds: int,
                 out: Path) -> dict[str, str]:
    """Every table (:func:`format_tables`) and the performance profiles into ``out``;
    returns the tables by file name."""
    tables = format_tables(results, counts, table_robots, seeds)
    out.mkdir(parents=True, exist_ok=True)
    for name, text in tables.items():
        (out / name).write_text(text)
    plot_performance_profiles(on_shared_episodes(results, counts), counts, out / PROFILES_PLOT)
    return tables


def results_of(document: dict) -> tuple[dict, list[int]]:
    """A ``results.json`` document's results (robot counts as ints) and its counts."""
    counts = [int(n) for n in document["counts"]]
    results = {s: {b: {int(n): m for n, m in c.items()} for b, c in r.items()}
               for s, r in document["results"].items()}
    return results, counts


def tables_of(document: dict, table_robots: int = 4) -> dict[str, str]:
    """Every markdown table of a ``results.json`` document, by file name (no files written)."""
    results, counts = results_of(document)
    return format_tables(results, counts, table_robots, int(document["seeds"]))


def tables_from_results(path: Path, out: Path, table_robots: int = 4) -> dict[str, str]:
    """Write the tables again from a ``results.json`` (no training): ``out`` gets the same
    markdown files as a run. Returns them by name."""
    document = json.loads(Path(path).read_text())
    results, counts = results_of(document)
    tables = write_tables(results, counts, table_robots, int(document["seeds"]), out)
    write_atomic(out / "marl_eval.json", json.dumps(to_marl_eval(document), indent=1))
    return tables


def gather_seeds(by_count: dict[int, dict[str, list[float]]], seeds: int,
                 processes: Processes) -> dict[int, dict[str, list[float]]]:
    """This process's seeds' values (``{robots: {metric: [its seeds]}}``) joined with every
    other process's, in seed order (:func:`train.run.multiprocess.gather_lanes`)."""
    if processes.count == 1:
        return by_count
    counts = sorted(by_count)
    names = sorted(m for m in by_count[counts[0]] if m != EPISODES_KEY)
    mine = np.asarray([[by_count[n][m] for m in names] for n in counts])  # [counts, M, seeds]
    every = gather_lanes(np.moveaxis(mine, -1, 0), seeds, processes)  # [seeds, counts, M]
    episodes = np.asarray([by_count[n][EPISODES_KEY] for n in counts])  # [counts, seeds, E]
    every_episode = gather_lanes(np.moveaxis(episodes, 1, 0), seeds, processes)  # [S, C, E]
    return {n: {**{m: every[:, i, j].tolist() for j, m in enumerate(names)},
                EPISODES_KEY: every_episode[:, i].tolist()}
            for i, n in enumerate(counts)}


# The results protocol's defaults (docs/results.md): enough seeds and episodes to decide, where
# the paper ran one seed of 25 episodes; the untrained baselines (one run each) play more.
RESULTS_SEEDS, RESULTS_EPISODES, RESULTS_BASELINE_EPISODES = 5, 100, 500

# Per-episode team success of every seed, ``[seeds, episodes]`` (every baseline plays the same
# episodes: the evaluation key is shared), for the paired comparisons with only_local.
EPISODES_KEY = "team_success_by_episode"
# A trained policy's team success per seed when it plays greedily and when it samples (the
# tables' other metrics come from the profile's mode: sampled for sgjax, greedy for socialgym)
PLAY_MODE_KEYS = ("team_success_greedy", "team_success_sampled")

SETTINGS = ("profile", "seeds", "total_steps", "num_envs", "episodes", "baseline_episodes",
            "counts", "seed", "time_limit")


def stored_run(path: Path, settings: dict[str, Any]) -> dict[str, Any]:
    """The ``results.json`` of an earlier run of the same ``settings`` (:data:`SETTINGS`), to
    resume: a ValueError naming the file and the first setting that differs."""
    try:
        document = json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise ValueError(f"{path}: not a results.json ({err})") from err
    if "episodes" in document and "baseline_episodes" not in document:
        # Written before untrained baselines had their own count: they played `episodes`.
        document["baseline_episodes"] = document["episodes"]
    for key in SETTINGS:
        if key not in document:
            raise ValueError(f"{path}: has no {key!r}; cannot tell whether it ran the same "
                             f"settings (written before --resume existed?)")
        if document[key] != settings[key]:
            raise ValueError(f"{path}: ran with {key} = {document[key]!r}, this run asks for "
                             f"{settings[key]!r}; resume with the same settings or another "
                             "--out")
    return document


def check_settings(profile: str, baselines: Sequence[str], seeds: int, episodes: int,
                   baseline_episodes: int, processes: Processes) -> None:
    """Errors for settings that cannot run, naming the argument."""
    if baseline_episodes < episodes:
        raise ValueError(f"--baseline-episodes ({baseline_episodes}) must be at least "
                         f"--episodes ({episodes}): the trained baselines' episodes are the "
                         "first of the untrained ones'")
    if profile not in PROFILES:
        raise ValueError(f"unknown profile {profile!r}; choose from {list(PROFILES)}")
    unknown = [b for b in baselines if b not in BASELINES]
    if unknown:
        raise ValueError(f"unknown baseline(s) {unknown}; choose from {list(BASELINES)}")
    if seeds < processes.count:
        raise ValueError(f"--seeds ({seeds}) must be at least --num-processes "
                         f"({processes.count}): the processes share the seeds")


class Run:
    """The cells of one reproduction (kept from an earlier run of the same settings, or run
    here) and the ``results.json`` document that holds them."""

    def __init__(self, settings: dict[str, Any], path: Path, resume: bool):
        self.settings, self.path = settings, path
        self.stored: dict[str, Any] = {"results": {}, "train_seconds": {}, "cell_seconds": {}}
        if resume and path.exists():
            self.stored = stored_run(path, settings)
        self.results: dict[str, dict[str, dict[int, dict[str, list[float]]]]] = {
            s: {b: {int(n): m for n, m in c.items()} for b, c in r.items()}
            for s, r in self.stored["results"].items()}
        self.timing: dict[str, float] = dict(self.stored["train_seconds"])
        self.cells: dict[str, dict[str, float]] = dict(self.stored.get("cell_seconds", {}))
        self.phases = Phases("compile training", "train", "evaluate", "write")

    def keep(self, scenario: str, name: str, by_count: dict, cell: dict[str, float]) -> None:
        """A finished cell and its phase seconds."""
        self.results.setdefault(scenario, {})[name] = by_count
        self.cells[f"{scenario}/{name}"] = cell
        for phase, key in (("compile training", "compile"), ("train", "train"),
                           ("evaluate", "evaluate")):
            self.phases.add(phase, cell[key])

    def seconds(self) -> dict[str, float]:
        """Every phase's seconds, the earlier runs' included."""
        earlier = self.stored.get("seconds", {})
        return {k: v + earlier.get(k, 0.0) for k, v in self.phases.seconds.items()}

    def document(self, scenarios: Sequence[str]) -> dict[str, Any]:
        """The ``results.json`` document (schema :data:`REPRODUCE`)."""
        results, settings, stored = self.results, self.settings, self.stored
        ordered = {s: {b: results[s][b] for b in BASELINES if b in results[s]}
                   for s in (*scenarios, *(s for s in results if s not in scenarios))
                   if s in results}
        seed = settings["seed"]
        made = provenance(settings, seeds={
            "training": [seed + i for i in range(settings["seeds"])],
            "evaluation": [seed + EVALUATION_SEED_OFFSET]},
            episodes_per_cell=settings["episodes"], seconds=self.seconds())
        # A resumed run: the cells kept were made by the earlier runs, whose blocks stay.
        earlier_runs = [*stored.get("earlier_provenance", []),
                        *([stored["provenance"]] if "provenance" in stored else [])]
        return {"schema_version": REPRODUCE, "provenance": made,
                "earlier_provenance": earlier_runs, **settings,
                "train_seconds": self.timing, "cell_seconds": self.cells,
                "seconds": self.seconds(),
                "runs": stored.get("runs", 1 if stored["results"] else 0) + 1,
                "results": {s: {b: {str(n): m for n, m in c.items()} for b, c in r.items()}
                            for s, r in ordered.items()}}


def run_cell(scenario: str, name: str, settings: dict[str, Any], out: Path,
             processes: Processes, resume: bool) -> tuple[dict, dict[str, float]]:
    """One (scenario, baseline) cell: trained (this process's share of the seeds, gathered)
    and evaluated, or evaluated only for an untrained baseline. Returns ``{robots: {metric:
    [per seed]}}`` and the cell's seconds (``compile``, ``train``, ``evaluate``)."""
    profile, seed, counts = settings["profile"], settings["seed"], settings["counts"]
    time_limit, total_steps = settings["time_limit"], settings["total_steps"]
    phases = Phases("compile", "train", "evaluate")
    kept = evaluation_path(out, scenario, name) if processes.count == 1 else None
    if BASELINES[name] is None:
        with phases.timing("evaluate"):
            by_count = evaluate_seeds(scenario, counts, settings["baseline_episodes"], seed,
                                      None, None, only_local_options(profile, time_limit), name,
                                      kept, resume)
        print(f"{scenario:>12} {name:>15}: not trained", flush=True)
        return by_count, phases.seconds
    share = lane_share(settings["seeds"], processes)
    if profile == "socialgym":
        config = socialgym_baseline_config(name, scenario, len(share), total_steps,
                                           seed + int(share[0]), counts,
                                           settings["episodes"], time_limit)
    else:
        config = baseline_config(name, scenario, len(share), total_steps,
                                 settings["num_envs"], seed + int(share[0]),
                                 75.0 if time_limit is None else time_limit)
    partial = partial_path(out, scenario, name) if processes.count == 1 else None
    trainer, runner, compile_s, train_s = train_baseline(config, partial, resume)
    phases.add("compile", compile_s)
    phases.add("train", train_s)
    with phases.timing("evaluate"):
        by_count = evaluate_seeds(scenario, counts, settings["episodes"], seed, trainer,
                                  runner, config.env.options, kept=kept, resume=resume)
        by_count = gather_seeds(by_count, settings["seeds"], processes)
    print(f"{scenario:>12} {name:>15}: trained {len(share)} seeds x {total_steps:,} steps in "
          f"{train_s:.0f} s (compiled in {compile_s:.0f} s)", flush=True)
    return by_count, phases.seconds


def reproduce(scenarios: Sequence[str], baselines: Sequence[str], seeds: int,
              total_steps: int, num_envs: int, counts: Sequence[int], episodes: int,
              table_robots: int, out: Path, seed: int = 0, time_limit: float | None = None,
              processes: Processes | None = None, profile: str = "sgjax",
              resume: bool = False, baseline_episodes: int | None = None) -> dict:
    """Train and evaluate every (scenario, baseline); write and print the two tables. Under
    several ``processes`` (``jax.distributed``) each trains its share of the seeds of every
    trained baseline, the values are gathered, and process 0 writes the outputs. ``profile``:
    ``sgjax`` or ``socialgym`` (the module doc); ``time_limit`` (s) overrides the profile's.

    Trained baselines play ``episodes`` episodes per seed and count, untrained ones
    (only_local, the classical controllers) ``baseline_episodes`` (default ``episodes``), of
    which the first ``episodes`` are the trained baselines' episodes: the episode keys come from
    one evaluation key and ``jax.random.split`` gives episode ``e`` the same key whatever the
    count (prefix-stable), so the paired comparison pairs those.

    ``out/results.json`` is written again after every cell, so a killed run loses at most the
    cell it was in; with ``resume`` the cells already there (from a run of the same settings)
    are kept, not run again, and the tables hold them beside the new ones."""
    processes = processes or Processes()
    baseline_episodes = episodes if baseline_episodes is None else int(baseline_episodes)
    check_settings(profile, baselines, seeds, episodes, baseline_episodes, processes)
    settings = {"profile": profile, "seeds": seeds, "total_steps": total_steps,
                "num_envs": num_envs if profile == "sgjax" else "the profile's",
                "episodes": episodes, "baseline_episodes": baseline_episodes,
                "counts": list(counts), "seed": seed, "time_limit": time_limit}
    path = out / "results.json"
    run = Run(settings, path, resume)
    for scenario in scenarios:
        for name in baselines:
            if name in run.results.get(scenario, {}):
                print(f"{scenario:>12} {name:>15}: kept from {path}", flush=True)
                continue
            by_count, cell = run_cell(scenario, name, settings, out, processes, resume)
            if BASELINES[name] is not None:
                run.timing[f"{scenario}/{name}"] = cell["train"]
            run.keep(scenario, name, by_count, cell)
            team = {n: np.nanmean(v["team_success"]) for n, v in by_count.items()}
            print("    team success by robots: " + ", ".join(f"{n}: {t:.2f}"
                                                          for n, t in team.items()))
            if processes.is_main:  # a killed run keeps every finished cell
                out.mkdir(parents=True, exist_ok=True)
                write_atomic(path, json.dumps(run.document(scenarios), indent=1))
                partial_path(out, scenario, name).unlink(missing_ok=True)
                evaluation_path(out, scenario, name).unlink(missing_ok=True)
    if not processes.is_main:
        print(f"process {processes.index}: done; process 0 writes the tables")
        return run.results
    write_results(run, scenarios, counts, table_robots, seeds, out)
    return run.results


def write_results(run: Run, scenarios: Sequence[str], counts: Sequence[int],
                  table_robots: int, seeds: int, out: Path) -> None:
    """The tables, ``results.json`` and ``marl_eval.json`` into ``out``; the tables and the
    phase times printed."""
    with run.phases.timing("write"):
        final = run.document(scenarios)
        final_results = {s: {b: {int(n): m for n, m in c.items()} for b, c in r.items()}
                         for s, r in final["results"].items()}
        tables = write_tables(final_results, counts, table_robots, seeds, out)
    document = run.document(scenarios)
    write_atomic(run.path, json.dumps(document, indent=1))
    write_atomic(out / "marl_eval.json", json.dumps(to_marl_eval(document), indent=1))
    for text in tables.values():
        print(f"\n{text}")
    kept = len(run.stored["train_seconds"])
    print(run.phases.line(" (evaluation includes its compiles)")
          + (f"; {kept} trained cells kept from {run.path}" if run.stored["results"] else ""))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m train.reproduce",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenarios", nargs="+", default=list(MINI_GAMES))
    parser.add_argument("--baselines", nargs="+", default=list(PAPER_BASELINES),
                        help=f"of {', '.join(BASELINES)} (default: the paper's five)")
    parser.add_argument("--seeds", type=int, default=RESULTS_SEEDS,
                        help=f"training seeds per trained baseline (default {RESULTS_SEEDS}: "
                             "the results protocol, docs/results.md)")
    parser.add_argument("--total-steps", type=int, default=None,
                        help="environment steps per seed (default: 2,000,000 for the sgjax "
                             "profile, Listing 1's 250,000 for socialgym)")
    parser.add_argument("--num-envs", type=int, default=256)
    parser.add_argument("--robots", nargs="+", type=int, default=list(PAPER.num_agents),
                        help="evaluation robot counts (default: the paper's)")
    parser.add_argument("--episodes", type=int, default=RESULTS_EPISODES,
                        help=f"per seed and robot count (default {RESULTS_EPISODES}, the "
                             f"results protocol; the paper played {PAPER.episodes})")
    parser.add_argument("--baseline-episodes", type=int, default=None,
                        help="per robot count for the untrained baselines (default: "
                             f"{RESULTS_BASELINE_EPISODES} or --episodes if more; at least "
                             "--episodes: the first --episodes of them are the trained "
                             "baselines' episodes)")
    parser.add_argument("--table-robots", type=int, default=4,
                        help="robot count of the metrics table")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--time-limit", type=float, default=None,
                        help="seconds per episode (default: the profile's, 75 s or 80 s)")
    parser.add_argument("--profile", choices=PROFILES, default="sgjax",
                        help="sgjax's settings, or each baseline as SocialGym 2.0 ran it "
                             "(see the module doc)")
    parser.add_argument("--out", default="runs/reproduce")
    parser.add_argument("--resume", action="store_true",
                        help="keep the cells already in --out/results.json (a run of the same "
                             "settings, e.g. one that was killed) and run only the others")
    parser.add_argument("--from-results", default=None, metavar="RESULTS_JSON",
                        help="write the tables again from a run's results.json into --out "
                             "(no training)")
    add_cache_arguments(parser)
    add_arguments(parser)
    args = parser.parse_args(argv)
    if args.from_results:
        for text in tables_from_results(Path(args.from_results), Path(args.out),
                                        args.table_robots).values():
            print(text)
        return
    try:
        cache_from_arguments(args)
        processes = initialize(args.coordinator, args.num_processes, args.process_id)
        total_steps = args.total_steps or (LISTING_1_STEPS if args.profile == "socialgym"
                                           else 2_000_000)
        reproduce(args.scenarios, args.baselines, args.seeds, total_steps, args.num_envs,
                  args.robots, args.episodes, args.table_robots, Path(args.out), args.seed,
                  args.time_limit, processes, args.profile, args.resume,
                  max(RESULTS_BASELINE_EPISODES, args.episodes)
                  if args.baseline_episodes is None else args.baseline_episodes)
    except ValueError as err:
        raise SystemExit(f"reproduce: {err}") from err


if __name__ == "__main__":
    main()
