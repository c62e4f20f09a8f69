"""Evaluation: policies x scenarios x robot counts x episodes, one batched computation each.

Python::

    from sgjax.evaluation.evaluate import evaluate
    results = evaluate(["doorway"], ["only_local"], num_agents=[3, 4], episodes=25,
                       out="runs/eval")

Command line: ``sgjax evaluate --scenario doorway --policy only_local --num-agents 3 4
--episodes 25 --out runs/eval`` (see :mod:`sgjax.command`). Each (scenario, policy) is one
:class:`sgjax.evaluation.runner.EpisodeRunner`, compiled once and played at every robot count:
``jit(scan(vmap(step_env)))`` until every episode has ended, with :mod:`sgjax.evaluation.metrics`
accumulated inside. :func:`evaluate_lanes` plays the policies of a scenario as the lanes of
one :class:`sgjax.evaluation.runner.LaneRunner` instead, one call per robot count (one compiled
program for the whole table; the same episodes and results), and :func:`lane_results` turns
such a batch into the same :class:`~sgjax.evaluation.statistics.ConfigResult` records.
Results are summarised per metric over episodes by :mod:`sgjax.evaluation.statistics` (mean, a
95% confidence interval: Wilson for yes/no episode metrics, Student t for the rest, and the
number of episodes with a value) and written by :mod:`sgjax.evaluation.report`. ``Episodes``,
``check_steps`` and ``with_zone_books`` live in :mod:`sgjax.evaluation.runner`.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from sgjax.environment.env import SocialNavEnv
from sgjax.environment.options import MakeOptions
from sgjax.environment.registry import make
from sgjax.evaluation import metrics
from sgjax.evaluation.policies import (
    BASELINES,
    Policy,
    RecurrentPolicy,
    load_policy,
    policy_options,
)
from sgjax.evaluation.protocols import PAPER
from sgjax.evaluation.provenance import provenance
from sgjax.evaluation.report import write_all
from sgjax.evaluation.runner import STEP_CHUNK, EpisodeRunner, Episodes, LaneRunner
from sgjax.evaluation.statistics import ConfigResult, Summary, summarize_metrics
from sgjax.types import EnvParams

__all__ = [
    "DEFAULT_EPISODES", "DEFAULT_NUM_AGENTS", "evaluate", "evaluate_lanes", "lane_results",
    "params_by_count", "policy_environment", "run_episodes", "summarize_episodes",
]

DEFAULT_NUM_AGENTS = PAPER.num_agents  # the paper's robot counts
DEFAULT_EPISODES = PAPER.episodes


def params_by_count(scenario: Any, counts: Sequence[int], **make_kwargs: Any
                    ) -> tuple[SocialNavEnv, dict[int, EnvParams]]:
    """One environment for every robot count in ``counts``, and its params at each count: made
    once with ``max_agents`` = the largest count (unless ``make_kwargs`` sets it); the count
    is a params value, so one compiled runner serves them all."""
    kwargs = {"max_agents": max(counts), **make_kwargs}
    env, params = make(scenario, num_agents=max(counts), **kwargs)
    by_count = {n: params.replace(num_agents=jnp.asarray(n, jnp.int32),
                                  min_agents=jnp.asarray(0, jnp.int32)) for n in counts}
    for n in counts:
        env.check_params(by_count[n])
    return env, by_count


def policy_environment(scenario: Any, counts: Sequence[int], policy: Any,
                       options: MakeOptions | None = None
                       ) -> tuple[SocialNavEnv, dict[int, EnvParams]]:
    """:func:`params_by_count` in ``options``, by default the options ``policy`` acts in (a
    checkpoint's from training, a velocity baseline's continuous actions:
    :func:`sgjax.evaluation.policies.policy_options`); ``max_agents`` is the options', else
    the largest count."""
    if options is None:
        options = policy_options(policy)
    return params_by_count(scenario, counts, options=options,
                           max_agents=options.robots.max_agents or max(counts))


def run_episodes(
    env: SocialNavEnv, params: EnvParams, policy: Policy | RecurrentPolicy | str, key: jax.Array,
    num_episodes: int, constants: metrics.MetricConstants = metrics.DEFAULT_CONSTANTS,
    record: bool = False, counterfactual: bool = False,
) -> Episodes:
    """Play ``num_episodes`` episodes at once and return their metrics on the host
    (``counterfactual``: with the counterfactual lanes and metrics; ``record``: every state,
    :class:`sgjax.evaluation.runner.EpisodeRunner`). A baseline given by name keeps its
    compiled run for the process: a later call in an equal environment with the same settings
    (another robot count or pedestrian setting of its params, say) plays the same program
    (``compile_seconds`` 0)."""
    if num_episodes < 1:
        raise ValueError(f"num_episodes must be at least 1, got {num_episodes}")
    env.check_params(params)
    settings = (num_episodes, int(params.max_steps), constants, record, counterfactual)
    if isinstance(policy, str) and policy in BASELINES:
        runner = _baseline_runner(env, policy, *settings)
    else:
        runner = _runner(env, load_policy(policy, env), *settings)
    return runner(key, params)


def _runner(env: SocialNavEnv, policy: Policy | RecurrentPolicy, num_episodes: int,
            max_steps: int, constants: metrics.MetricConstants, record: bool,
            counterfactual: bool) -> EpisodeRunner:
    return EpisodeRunner(env, policy, num_episodes, max_steps, constants, record=record,
                         counterfactual=counterfactual)


@functools.lru_cache(maxsize=16)
def _baseline_runner(env: SocialNavEnv, name: str, *settings: Any) -> EpisodeRunner:
    """The runner of a baseline (by name) in ``env``, kept for the process: calls at other
    robot counts or pedestrian settings (params values) play its compiled program again
    (environments are equal when their static configurations are)."""
    return _runner(env, load_policy(name, env), *settings)


def steps_played(episodes: Episodes, params: EnvParams) -> int:
    """Steps a batch ran: its longest episode, rounded up to the runner's chunk of steps (at
    most the time limit); for a :class:`~sgjax.evaluation.runner.LaneRunner`'s batch, the
    longest of every configuration's."""
    longest = int(np.nanmax(episodes.values["episode_length"]))
    return min(int(params.max_steps), -(-longest // STEP_CHUNK) * STEP_CHUNK)


def summarize_episodes(episodes: Episodes) -> dict[str, Summary]:
    """Every metric of a batch summarised over its episodes (:mod:`sgjax.evaluation.statistics`)."""
    return summarize_metrics(episodes.values)


def evaluate(
    scenarios: Sequence[str], policies: Sequence[str | Policy | RecurrentPolicy],
    num_agents: Sequence[int] = DEFAULT_NUM_AGENTS, episodes: int = DEFAULT_EPISODES,
    seed: int = 0, out: str | Path | None = None,
    options: MakeOptions | Sequence[MakeOptions | None] | None = None,
    constants: metrics.MetricConstants = metrics.DEFAULT_CONSTANTS,
    log: Callable[[str], None] | None = print,
    policy_names: Sequence[str] | None = None,
    counterfactual: bool = False,
    deterministic: bool | None = None,
    record: str | Path | None = None,
) -> list[ConfigResult]:
    """Evaluate every policy on every scenario and robot count; with ``out``, write
    ``metrics.json``, ``metrics.csv``, ``table.md`` and PNG charts there
    (:mod:`sgjax.evaluation.report`).

    ``policies`` are baseline names, ``"module:function"`` specs, trainer checkpoints or
    policy objects (named ``policy<i>`` in the outputs); ``policy_names`` name them in the
    outputs. ``options`` are the :func:`sgjax.make` options
    (:class:`~sgjax.environment.options.MakeOptions`: observation preset, robots, time limit,
    ...) of every policy, or a sequence of one per policy; None (the default, or an entry):
    the options the policy acts in (:func:`sgjax.evaluation.policies.policy_options`: a
    checkpoint's from training, continuous actions for the velocity baselines). Every
    configuration uses the same ``seed``.

    Each (scenario, policy) compiles once: the environment is made with ``max_agents`` = the
    largest count (unless the options set it) and every robot count is a params value of
    the same compiled run. ``counterfactual`` adds the lanes of
    :mod:`sgjax.evaluation.counterfactual`
    (each robot alone, the episode without each robot: ``1 + 2 max_agents`` times the work) and
    their metrics; the episodes and every other metric are the same either way.
    ``deterministic`` makes trained checkpoints act greedily (True) or sample their actions
    (False) instead of their run's ``evaluation.deterministic``
    (:func:`sgjax.evaluation.policies.load_policy`;
    baselines and policy objects are unaffected). ``record``: a folder where each
    configuration's first episode is written as an MCAP file for Foxglove
    (``<scenario>_<policy>_<robots>.mcap``, :mod:`sgjax.evaluation.episode_log`)."""
    if not scenarios or not policies or not num_agents:
        raise ValueError("evaluate: scenarios, policies and num_agents must not be empty")
    if episodes < 1:
        raise ValueError(f"evaluate: episodes must be at least 1, got {episodes}")
    by_policy = ([options] * len(policies) if options is None or isinstance(options, MakeOptions)
                 else list(options))
    if len(by_policy) != len(policies):
        raise ValueError(f"evaluate: {len(by_policy)} options for {len(policies)} policies; "
                         "give one MakeOptions for all, or one per policy")
    results = []
    key = jax.random.key(seed)
    for scenario in scenarios:
        for p, policy in enumerate(policies):
            name = (policy_names[p] if policy_names is not None
                    else policy if isinstance(policy, str) else f"policy{p}")
            t0 = time.perf_counter()
            played_in = by_policy[p] if by_policy[p] is not None else policy_options(policy)
            env, by_count = policy_environment(scenario, num_agents, policy, played_in)
            params = by_count[num_agents[0]]
            runner = EpisodeRunner(env, load_policy(policy, env, deterministic), episodes,
                                   int(params.max_steps), constants, counterfactual=counterfactual,
                                   record_lanes=None if record is None else [0])
            compiled, _ = runner.compile(key, params)
            compile_seconds = time.perf_counter() - t0
            for n in num_agents:
                params = by_count[n]
                batch = runner.play_compiled(compiled, key, params, compile_seconds)
                result = _config_result(str(scenario), name, n, episodes, seed, params, batch,
                                        time.perf_counter() - t0, counterfactual,
                                        played_in.to_dict())
                if record is not None:
                    record_first_episode(Path(record), scenario, name, env, params, batch)
                results.append(result)
                if log is not None:
                    log(_progress_line(result))
                t0, compile_seconds = time.perf_counter(), 0.0
    if out is not None:
        made = provenance(seeds={"evaluation": [seed]}, episodes_per_cell=episodes)
        paths = write_all(results, Path(out), constants, made)
        if log is not None:
            log("wrote " + ", ".join(str(p) for p in paths))
    return results


def _config_result(scenario: str, name: str, n: int, episodes: int, seed: int, params: EnvParams,
                   batch: Episodes, seconds: float, counterfactual: bool,
                   options: dict[str, Any] | None = None) -> ConfigResult:
    """The :class:`ConfigResult` of one configuration's played ``batch`` (``options``: the
    make options it was played in, :meth:`MakeOptions.to_dict`)."""
    return ConfigResult(
        scenario=scenario, policy=name, num_agents=n, episodes=episodes, seed=seed,
        dt=float(params.dt), max_steps=int(params.max_steps), metrics=summarize_episodes(batch),
        seconds=seconds, compile_seconds=batch.compile_seconds, run_seconds=batch.run_seconds,
        counterfactual=counterfactual, steps_played=steps_played(batch, params),
        options=options)


def record_first_episode(folder: Path, scenario: str, policy: str, env: SocialNavEnv,
                         params: EnvParams, batch: Episodes) -> Path:
    """Write the first episode recorded in ``batch`` (``record_lanes=[0]``) as
    ``folder/<scenario>_<policy>_<robots>.mcap`` with its metrics."""
    from sgjax.evaluation.episode_log import write_mcap
    from sgjax.evaluation.render import recorded_map

    states = jax.tree.map(lambda leaf: leaf[:, 0], batch.states)
    robots = int(np.asarray(params.num_agents))
    stem = "_".join(Path(str(part)).stem.replace(":", "-") for part in (scenario, policy))
    return write_mcap(folder / f"{stem}_{robots}.mcap", recorded_map(scenario, states),
                      states, params, env.config.layout,
                      int(batch.values["episode_length"][0]), rewards=batch.rewards[:, 0],
                      metrics={k: float(v[0]) for k, v in batch.values.items()})


def evaluate_lanes(
    scenario: str, policies: Sequence[str | Policy | RecurrentPolicy],
    num_agents: Sequence[int] = DEFAULT_NUM_AGENTS, episodes: int = DEFAULT_EPISODES,
    seed: int = 0, options: MakeOptions | None = None,
    constants: metrics.MetricConstants = metrics.DEFAULT_CONSTANTS,
    policy_names: Sequence[str] | None = None, deterministic: bool | None = None,
    record: tuple[int, int, int] | None = None, counts_at_once: bool = False,
) -> tuple[list[ConfigResult], dict[str, np.ndarray], Any]:
    """:func:`evaluate` of one scenario from one compiled program: the policies are the lanes
    of one :class:`~sgjax.evaluation.runner.LaneRunner`, called once per robot count (the
    count is an argument), or with ``counts_at_once`` once with every count as lanes too.
    The results, in :func:`evaluate`'s order (policy, then count), are those of
    ``evaluate([scenario], policies, num_agents, episodes, seed, options)``, timings aside:
    the same episodes and keys. Every policy acts in one environment: ``options``, by default
    the first policy's (:func:`sgjax.evaluation.policies.policy_options`).

    A call plays until the slowest episode of any of its lanes has ended: once per count, each
    count stops with its slowest policy; all at once, everything runs as long as the slowest
    episode of all. On the 2-core CPU one call per count was also faster per step (a batch of
    ``P x E`` environments, not ``P x K x E``) and its values equal :func:`evaluate`'s to the
    bit; the step compiled for the larger batch of ``counts_at_once`` rounds some continuous
    metrics differently in the last float32 digits (relative 1e-7; no outcome changed).

    ``record``: ``(policy index, robot count, episode)`` to record while it is evaluated.
    Returns ``(results, values, states)``: every metric per episode ``{name: [P, K, E]}``
    and the recorded episode's states ``[T + 1, ...]`` (None without ``record``)."""
    if not policies or not num_agents:
        raise ValueError("evaluate_lanes: policies and num_agents must not be empty")
    if record is not None and record[1] not in num_agents:
        raise ValueError(f"evaluate_lanes: record at {record[1]} robots, not one of "
                         f"{list(num_agents)}")
    t0 = time.perf_counter()
    played_in = options if options is not None else policy_options(policies[0])
    env, by_count = policy_environment(scenario, num_agents, policies[0], played_in)
    params = by_count[num_agents[0]]
    calls = [list(num_agents)] if counts_at_once else [[n] for n in num_agents]
    lane = None if record is None else [(
        record[0] * len(calls[0]) + (calls[0].index(record[1]) if counts_at_once else 0),
        record[2])]
    runner = LaneRunner(env, [load_policy(p, env, deterministic) for p in policies],
                        len(calls[0]), episodes, int(params.max_steps), constants,
                        record_lanes=lane)
    key = jax.random.key(seed)
    compiled, _ = runner.compile(key, params, jnp.asarray(calls[0], jnp.int32))
    names = [policy_names[p] if policy_names is not None
             else policy if isinstance(policy, str) else f"policy{p}"
             for p, policy in enumerate(policies)]
    seconds, per_call, recorded = time.perf_counter() - t0, [], None
    for counts in calls:
        batch = runner.play_compiled(compiled, key, params, seconds,
                                     (jnp.asarray(counts, jnp.int32),))
        per_call.append((batch.values, lane_results(scenario, names, counts, seed, params,
                                                    batch, played_in.to_dict())))
        if record is not None and record[1] in counts:
            recorded = jax.tree.map(lambda leaf: leaf[:, 0], batch.states)
        seconds = 0.0
    k = len(calls[0])
    results = [r for p in range(len(policies)) for _, call in per_call
               for r in call[p * k:(p + 1) * k]]
    values = {name: np.concatenate([v[name].reshape((len(policies), k, episodes))
                                    for v, _ in per_call], axis=1) for name in per_call[0][0]}
    return results, values, recorded


def lane_results(scenario: str, names: Sequence[str], num_agents: Sequence[int], seed: int,
                 params: EnvParams, batch: Episodes,
                 options: dict[str, Any] | None = None) -> list[ConfigResult]:
    """The :class:`~sgjax.evaluation.statistics.ConfigResult` of every configuration of a
    :class:`~sgjax.evaluation.runner.LaneRunner`'s batch (values ``{name: [C, E]}``,
    configuration ``p * K + k`` being ``names[p]`` at ``num_agents[k]``), in
    :func:`evaluate`'s order. Timings: the program's run time is shared evenly (every lane
    costs the same), its compile time goes to the first configuration (the others reused it),
    and every configuration played the steps the program ran (:func:`steps_played`);
    ``options``: the make options every lane was played in (:meth:`MakeOptions.to_dict`)."""
    count = len(names) * len(num_agents)
    lengths = batch.values["episode_length"]
    if np.shape(lengths)[0] != count:
        raise ValueError(f"lane_results: {np.shape(lengths)[0]} configurations in the batch, "
                         f"{len(names)} policies x {len(num_agents)} counts named")
    run = (batch.run_seconds or 0.0) / count
    steps = steps_played(batch, params)
    results = []
    for c in range(count):
        compile_seconds = (batch.compile_seconds or 0.0) if c == 0 else 0.0
        results.append(ConfigResult(
            scenario=str(scenario), policy=names[c // len(num_agents)],
            num_agents=int(num_agents[c % len(num_agents)]), episodes=int(np.shape(lengths)[1]),
            seed=seed, dt=float(params.dt), max_steps=int(params.max_steps),
            metrics=summarize_metrics({k: v[c] for k, v in batch.values.items()}),
            seconds=compile_seconds + run, compile_seconds=compile_seconds, run_seconds=run,
            steps_played=steps, options=options))
    return results


def _progress_line(result: ConfigResult) -> str:
    m = result.metrics
    rate = result.agent_steps_per_second
    compiled = ("compiled run reused" if not result.compile_seconds
                else f"compiled in {result.compile_seconds:.1f} s")
    speed = "" if rate is None else f", {compiled}, {rate:,.0f} agent-steps/s"
    return (f"{result.scenario:>12} {result.policy:>18} {result.num_agents:>3} robots: team "
            f"success {m['team_success'].mean:.2f}, success {m['success'].mean:.2f}, collisions "
            f"{m['collisions'].mean:.2f}, length {m['episode_length'].mean:.0f} steps "
            f"({result.seconds:.1f} s{speed})")
