"""Evaluation: policies x scenarios x robot counts x episodes, one batched computation each.

Python::

    from sgjax.evaluate import evaluate
    results = evaluate(["doorway"], ["only_local"], num_agents=[3, 4], episodes=25,
                       out="runs/eval")

Command line: ``sgjax evaluate --scenario doorway --policy only_local --num-agents 3 4
--episodes 25 --out runs/eval`` (see :mod:`sgjax.cli`). Each configuration runs its episodes as
one ``jit(scan(vmap(step_env)))`` for the time limit; an episode's state is frozen once it ends,
and :mod:`sgjax.metrics` accumulates inside the scan. Results are summarised per metric over
episodes by :mod:`sgjax.statistics` (mean, a 95% confidence interval: Wilson for yes/no episode
metrics, Student t for the rest, and the number of episodes with a value) and written by
:mod:`sgjax.report`. The statistics names (``summarize``, ``Summary``, ``ConfigResult``, ...)
are re-exported here.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from sgjax import metrics
from sgjax.env import EnvParams, SocialNavEnv
from sgjax.policies import Policy, RecurrentPolicy, load_policy, policy_make_kwargs
from sgjax.registry import make
from sgjax.report import write_all
from sgjax.statistics import (
    CONFIDENCE,
    ConfigResult,
    Summary,
    summarize,
    summarize_metrics,
    t_interval,
    wilson_interval,
)

__all__ = [
    "CONFIDENCE", "DEFAULT_EPISODES", "DEFAULT_NUM_AGENTS", "ConfigResult", "Episodes",
    "Summary", "check_steps", "episode_runner", "evaluate", "params_by_count", "run_episodes",
    "summarize",
    "summarize_episodes", "t_interval", "wilson_interval", "with_zone_books",
]

DEFAULT_NUM_AGENTS = (3, 4, 5, 7, 10)
DEFAULT_EPISODES = 25


def with_zone_books(env: SocialNavEnv) -> SocialNavEnv:
    """The same environment, keeping conflict-zone books for the order-violation metrics."""
    if env.config.track_zones:
        return env
    return SocialNavEnv(dataclasses.replace(env.config, track_zones=True), env.default_params)


@dataclasses.dataclass
class Episodes:
    """Host results of a batch of ``E`` episodes."""

    values: dict[str, np.ndarray]  # per-episode value of every metric, [E]
    robot: dict[str, np.ndarray]  # per-robot values of robot-level metrics, [E, R]
    states: Any = None  # with record=True: EnvState stacked [T + 1, E, ...] (T = time limit)
    compile_seconds: float | None = None  # compiling the batched run
    run_seconds: float | None = None  # running it once compiled (results on the host)


def episode_runner(
    env: SocialNavEnv, params: EnvParams, policy: Policy | RecurrentPolicy, num_episodes: int,
    constants: metrics.MetricConstants = metrics.DEFAULT_CONSTANTS, record: bool = False,
) -> Callable[[jax.Array], tuple]:
    """A jitted ``run(key, params) -> (values, robot, states)`` playing ``num_episodes``
    episodes of ``env`` under ``policy`` for the time limit (``states`` is None unless
    ``record``).

    ``params`` is an argument, so one compiled ``run`` serves every robot count up to
    ``env.max_agents`` (and every pedestrian count, radius or weight the params hold): make the
    environment once at the largest count and pass each count's params. The ``params`` given
    here fix the number of steps scanned (their ``max_steps``); ``run`` needs params whose
    ``max_steps`` is at most that (:func:`check_steps`), as an episode is cut off there."""
    env = with_zone_books(env)
    num_steps = int(params.max_steps)
    reset = jax.vmap(env.reset, in_axes=(0, None))
    step = jax.vmap(env.step_env, in_axes=(0, 0, 0, None))
    if isinstance(policy, RecurrentPolicy):
        act = jax.vmap(policy.step, in_axes=(0, 0, 0, 0, None))
        first_memory = jax.vmap(lambda _: policy.init(env.max_agents))(jnp.arange(num_episodes))
    else:
        plain = jax.vmap(policy, in_axes=(0, 0, 0, None))
        act = lambda memory, *args: (memory, plain(*args))  # noqa: E731
        first_memory = jnp.zeros(num_episodes)
    done_of = jax.vmap(metrics.episode_done)
    update = jax.vmap(lambda m, s0, s1, info, done, params: metrics.update(
        m, s0, s1, info, done, params, env.config, constants),
        in_axes=(0, 0, 0, 0, 0, None))
    finalize = jax.vmap(lambda m, s, params: metrics.finalize(m, s, params, constants),
                        in_axes=(0, 0, None))

    def one_step(carry, key, params):
        obs, state, tally, memory = carry
        k_act, k_step = jax.random.split(key)
        memory, actions = act(memory, obs, jax.random.split(k_act, num_episodes), state, params)
        next_obs, next_state, _, term, trunc, info = step(
            jax.random.split(k_step, num_episodes), state, actions, params)
        tally_next = update(tally, state, next_state, info, done_of(next_state, term, trunc),
                            params)

        def keep(new, old):  # ended episodes stay as they ended
            running = tally.running.reshape((-1,) + (1,) * (new.ndim - 1))
            return jnp.where(running, new, old)

        carry = (keep(next_obs, obs), jax.tree.map(keep, next_state, state), tally_next, memory)
        return carry, (carry[1] if record else None)

    @jax.jit
    def run(key: jax.Array, params: EnvParams) -> tuple:
        k_reset, k_steps = jax.random.split(key)
        obs, state = reset(jax.random.split(k_reset, num_episodes), params)
        tally = jax.vmap(lambda _: metrics.start(env.max_agents, constants))(
            jnp.arange(num_episodes))
        (_, final, tally, _), states = jax.lax.scan(
            lambda carry, k: one_step(carry, k, params), (obs, state, tally, first_memory),
            jax.random.split(k_steps, num_steps))
        robot, episode = finalize(tally, final, params)
        values = jax.vmap(metrics.per_episode)(robot, episode)
        if record:
            states = jax.tree.map(lambda first, rest: jnp.concatenate([first[None], rest]),
                                  state, states)
        return values, robot, states

    return run


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


def check_steps(params: EnvParams, num_steps: int, where: str) -> None:
    """Raise unless episodes under ``params`` end within ``num_steps`` steps (the length a
    runner from :func:`episode_runner` was built for)."""
    if int(params.max_steps) > num_steps:
        raise ValueError(f"{where}: these params run episodes of {int(params.max_steps)} steps, "
                         f"but the runner was built for {num_steps} (a longer time limit needs "
                         "its own runner)")


def run_episodes(
    env: SocialNavEnv, params: EnvParams, policy: Policy | RecurrentPolicy | str, key: jax.Array,
    num_episodes: int, constants: metrics.MetricConstants = metrics.DEFAULT_CONSTANTS,
    record: bool = False,
) -> Episodes:
    """Play ``num_episodes`` episodes at once and return their metrics on the host."""
    if num_episodes < 1:
        raise ValueError(f"num_episodes must be at least 1, got {num_episodes}")
    env.check_params(params)
    run = episode_runner(env, params, load_policy(policy, env), num_episodes, constants, record)
    t0 = time.perf_counter()
    compiled = run.lower(key, params).compile()
    return _play(compiled, key, params, time.perf_counter() - t0)


def _play(compiled: Callable, key: jax.Array, params: EnvParams, compile_seconds: float
          ) -> Episodes:
    """Run a compiled episode runner and bring its results to the host."""
    t0 = time.perf_counter()
    values, robot, states = jax.device_get(compiled(key, params))
    return Episodes(values={k: np.asarray(v) for k, v in values.items()},
                    robot={k: np.asarray(v) for k, v in robot.items()}, states=states,
                    compile_seconds=compile_seconds, run_seconds=time.perf_counter() - t0)


def summarize_episodes(episodes: Episodes) -> dict[str, Summary]:
    """Every metric of a batch summarised over its episodes (:mod:`sgjax.statistics`)."""
    return summarize_metrics(episodes.values)


def evaluate(
    scenarios: Sequence[str], policies: Sequence[str | Policy | RecurrentPolicy],
    num_agents: Sequence[int] = DEFAULT_NUM_AGENTS, episodes: int = DEFAULT_EPISODES,
    seed: int = 0, out: str | Path | None = None, make_kwargs: dict[str, Any] | None = None,
    constants: metrics.MetricConstants = metrics.DEFAULT_CONSTANTS,
    log: Callable[[str], None] | None = print,
    policy_names: Sequence[str] | None = None,
) -> list[ConfigResult]:
    """Evaluate every policy on every scenario and robot count; with ``out``, write
    ``metrics.json``, ``metrics.csv``, ``table.md`` and PNG charts there (:mod:`sgjax.report`).

    ``policies`` are baseline names, ``"module:function"`` specs, trainer checkpoints or
    policy objects (named ``policy<i>`` in the outputs); ``make_kwargs`` go to
    :func:`sgjax.make` (observation preset, robots, time limit, ...) on top of the settings a
    checkpoint was trained with; ``policy_names`` name them in the outputs. Every
    configuration uses the same ``seed``.

    Each (scenario, policy) compiles once: the environment is made with ``max_agents`` = the
    largest count (unless ``make_kwargs`` sets it) and every robot count is a params value of
    the same compiled run."""
    if not scenarios or not policies or not num_agents:
        raise ValueError("evaluate: scenarios, policies and num_agents must not be empty")
    if episodes < 1:
        raise ValueError(f"evaluate: episodes must be at least 1, got {episodes}")
    results = []
    key = jax.random.key(seed)
    for scenario in scenarios:
        for p, policy in enumerate(policies):
            name = (policy_names[p] if policy_names is not None
                    else policy if isinstance(policy, str) else f"policy{p}")
            t0 = time.perf_counter()
            env, by_count = params_by_count(
                scenario, num_agents, **policy_make_kwargs(policy), **(make_kwargs or {}))
            params = by_count[num_agents[0]]
            run = episode_runner(env, params, load_policy(policy, env), episodes, constants)
            compiled = run.lower(key, params).compile()
            compile_seconds = time.perf_counter() - t0
            for n in num_agents:
                params = by_count[n]
                batch = _play(compiled, key, params, compile_seconds)
                result = ConfigResult(
                    scenario=str(scenario), policy=name, num_agents=n, episodes=episodes,
                    seed=seed, dt=float(params.dt), max_steps=int(params.max_steps),
                    metrics=summarize_episodes(batch), seconds=time.perf_counter() - t0,
                    compile_seconds=batch.compile_seconds, run_seconds=batch.run_seconds)
                results.append(result)
                if log is not None:
                    log(_progress_line(result))
                t0, compile_seconds = time.perf_counter(), 0.0
    if out is not None:
        paths = write_all(results, Path(out), constants)
        if log is not None:
            log("wrote " + ", ".join(str(p) for p in paths))
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
