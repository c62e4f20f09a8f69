"""Evaluation: policies x scenarios x robot counts x episodes, one batched computation each.

Python::

    from sgjax.evaluation.evaluate import evaluate
    results = evaluate(["doorway"], ["only_local"], num_agents=[3, 4], episodes=25,
                       out="runs/eval")

Command line: ``sgjax evaluate --scenario doorway --policy only_local --num-agents 3 4
--episodes 25 --out runs/eval`` (see :mod:`sgjax.command`). Each configuration runs its episodes as
one ``jit(scan(vmap(step_env)))`` for the time limit (stopping early once every episode has
ended); an episode's state is frozen once it ends,
and :mod:`sgjax.evaluation.metrics` accumulates inside the scan. Results are summarised per metric
over
episodes by :mod:`sgjax.evaluation.statistics` (mean, a 95% confidence interval: Wilson for yes/no
episode
metrics, Student t for the rest, and the number of episodes with a value) and written by
:mod:`sgjax.evaluation.report`.
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

from sgjax.environment.env import SocialNavEnv
from sgjax.environment.options import MakeOptions
from sgjax.environment.registry import make
from sgjax.evaluation import counterfactual as cf
from sgjax.evaluation import metrics
from sgjax.evaluation.policies import Policy, RecurrentPolicy, load_policy, policy_options
from sgjax.evaluation.protocols import PAPER
from sgjax.evaluation.report import write_all
from sgjax.evaluation.statistics import ConfigResult, Summary, summarize_metrics
from sgjax.types import EnvParams

__all__ = [
    "DEFAULT_EPISODES", "DEFAULT_NUM_AGENTS", "Episodes", "check_steps", "episode_runner",
    "evaluate", "params_by_count", "run_episodes", "summarize_episodes", "with_zone_books",
]

DEFAULT_NUM_AGENTS = PAPER.num_agents  # the paper's robot counts
STEP_CHUNK = 32  # steps per chunk of the runner's early-stopping loop
DEFAULT_EPISODES = PAPER.episodes


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
    counterfactual: bool = False, stop_early: bool = True,
) -> Callable[[jax.Array], tuple]:
    """A jitted ``run(key, params) -> (values, robot, states)`` playing ``num_episodes``
    episodes of ``env`` under ``policy`` for the time limit (``states`` is None unless
    ``record``).

    ``params`` is an argument, so one compiled ``run`` serves every robot count up to
    ``env.max_agents`` (and every pedestrian count, radius or weight the params hold): make the
    environment once at the largest count and pass each count's params. The ``params`` given
    here fix the number of steps scanned (their ``max_steps``); ``run`` needs params whose
    ``max_steps`` is at most that (:func:`check_steps`), as an episode is cut off there.

    ``counterfactual`` also plays every episode with each robot alone and without each robot
    (:mod:`sgjax.evaluation.counterfactual`: ``1 + 2R`` times the work) and fills in the
    counterfactual
    metrics (NaN otherwise). The episodes themselves are the same either way.

    ``stop_early`` (unless ``record``) stops stepping once every episode has ended; False steps
    through the whole time limit (same results; for benchmarks of the step)."""
    every_step = record or not stop_early
    env = with_zone_books(env)
    num_steps = int(params.max_steps)
    num_robots = env.max_agents
    reset = jax.vmap(env.reset, in_axes=(0, None))
    reset_lanes = jax.vmap(env.reset_subset, in_axes=(0, None, 0))
    step = jax.vmap(env.step_env, in_axes=(0, 0, 0, None))
    if isinstance(policy, RecurrentPolicy):
        act = jax.vmap(policy.step, in_axes=(0, 0, 0, 0, None))
        first_memory = lambda n: jax.vmap(lambda _: policy.init(num_robots))(  # noqa: E731
            jnp.arange(n))
    else:
        plain = jax.vmap(policy, in_axes=(0, 0, 0, None))
        act = lambda memory, *args: (memory, plain(*args))  # noqa: E731
        first_memory = jnp.zeros
    done_of = jax.vmap(metrics.episode_done)
    update = jax.vmap(lambda m, s0, s1, info, done, params: metrics.update(
        m, s0, s1, info, done, params, env.config, constants),
        in_axes=(0, 0, 0, 0, 0, None))
    finalize = jax.vmap(lambda m, s, params: metrics.finalize(m, s, params, constants),
                        in_axes=(0, 0, None))

    def play(params: EnvParams, obs: jax.Array, state: Any, lanes: int, keys: jax.Array,
             hook: Callable | None = None, extra: Any = None, emit: Callable | None = None
             ) -> tuple:
        """Play ``num_episodes x lanes`` episodes (episode-major) for ``num_steps``; the lanes
        of an episode share its per-step keys. ``hook(extra, prev, state, running)`` folds each
        step into ``extra``; ``emit(state)`` is returned for every step ``[num_steps, ...]``.

        Unless ``every_step``, the steps run in chunks of ``STEP_CHUNK`` inside a
        ``while_loop`` that stops once every episode has ended: an ended episode is frozen and
        changes nothing, so the results are the same as running the whole time limit (tested),
        and a batch whose episodes all end early costs only the steps it took."""
        count = num_episodes * lanes
        tally = jax.vmap(lambda _: metrics.start(num_robots, constants,
                                                 state.zones.phase.shape[-1]))(jnp.arange(count))

        def per_lane(keys: jax.Array) -> jax.Array:
            return keys if lanes == 1 else keys[jnp.arange(count) // lanes]

        def one_step(carry, key):
            obs, state, tally, memory, extra = carry
            k_act, k_step = jax.random.split(key)
            memory, actions = act(memory, obs, per_lane(jax.random.split(k_act, num_episodes)),
                                  state, params)
            next_obs, next_state, _, term, trunc, info = step(
                per_lane(jax.random.split(k_step, num_episodes)), state, actions, params)
            tally_next = update(tally, state, next_state, info, done_of(next_state, term, trunc),
                                params)

            def keep(new, old):  # ended episodes stay as they ended
                running = tally.running.reshape((-1,) + (1,) * (new.ndim - 1))
                return jnp.where(running, new, old)

            kept = jax.tree.map(keep, next_state, state)
            if hook is not None:
                extra = hook(extra, state, kept, tally.running)
            carry = (keep(next_obs, obs), kept, tally_next, memory, extra)
            return carry, (None if emit is None else emit(kept))

        start = (obs, state, tally, first_memory(count), extra)
        if every_step:
            (_, final, tally, _, extra), out = jax.lax.scan(one_step, start, keys)
            return final, tally, extra, out
        chunk = min(STEP_CHUNK, num_steps)
        chunks = -(-num_steps // chunk)
        # Steps past the time limit (padding the last chunk) find every episode ended.
        padded = keys[jnp.minimum(jnp.arange(chunks * chunk), num_steps - 1)]
        padded = padded.reshape((chunks, chunk) + padded.shape[1:])
        rows = (None if emit is None else jax.tree.map(
            lambda v: jnp.zeros((chunks * chunk,) + v.shape, v.dtype), emit(state)))

        def unfinished(loop: tuple) -> jax.Array:
            i, carry, _ = loop
            return (i < chunks) & jnp.any(carry[2].running)

        def run_chunk(loop: tuple) -> tuple:
            i, carry, rows = loop
            carry, out = jax.lax.scan(one_step, carry, padded[i])
            if emit is not None:
                rows = jax.tree.map(lambda r, o: jax.lax.dynamic_update_slice_in_dim(
                    r, o, i * chunk, axis=0), rows, out)
            return i + 1, carry, rows

        done, (_, final, tally, _, extra), rows = jax.lax.while_loop(
            unfinished, run_chunk, (jnp.zeros((), jnp.int32), start, rows))
        out = None
        if emit is not None:  # the rows never played hold the frozen final state's
            played = jnp.arange(chunks * chunk) < done * chunk
            out = jax.tree.map(
                lambda r, last: jnp.where(played.reshape((-1,) + (1,) * last.ndim), r,
                                          last[None])[:num_steps], rows, emit(final))
        return final, tally, extra, out

    def by_episode(tree: Any, lanes: int) -> Any:  # [E * L, ...] -> [E, L, ...]
        return jax.tree.map(lambda v: v.reshape((num_episodes, lanes) + v.shape[1:]), tree)

    def run_counterfactual(reset_keys: jax.Array, step_keys: jax.Array, params: EnvParams
                           ) -> tuple:
        # The robots alone: lane i of each episode keeps robot i; keep its positions.
        lanes = num_robots
        masks = jnp.tile(cf.alone_masks(num_robots), (num_episodes, 1))
        obs, state = reset_lanes(jnp.repeat(reset_keys, lanes, axis=0), params, masks)
        own = jnp.arange(num_robots)

        def own_xy(s: Any) -> jax.Array:  # [E, R, 2]: robot i in lane i
            r = by_episode(s.robots, lanes)
            return jnp.stack([r.x[:, own, own], r.y[:, own, own]], axis=-1)

        _, alone, _, path = play(params, obs, state, lanes, step_keys, emit=own_xy)
        path = jnp.concatenate([own_xy(state)[None], path])  # [T + 1, E, R, 2]
        arrived = by_episode(alone.arrived_at, lanes)[:, own, own]
        solo = cf.SoloPaths(x=jnp.moveaxis(path[..., 0], 0, -1),
                            y=jnp.moveaxis(path[..., 1], 0, -1), arrived_at=arrived)

        # The episode (lane 0) and the episode without each robot (lane 1 + i).
        lanes = 1 + num_robots
        masks = jnp.tile(cf.main_masks(num_robots), (num_episodes, 1))
        obs, state = reset_lanes(jnp.repeat(reset_keys, lanes, axis=0), params, masks)

        def compare(c: cf.Tally, prev: Any, now: Any, running: jax.Array) -> cf.Tally:
            return cf.update(c, solo, by_episode(prev, lanes), by_episode(now, lanes),
                             running.reshape(num_episodes, lanes))

        first = by_episode(state.robots, lanes)
        c0 = cf.start(first.x[:, 0], first.y[:, 0], solo)
        final, tally, c, out = play(
            params, obs, state, lanes, step_keys, hook=compare, extra=c0,
            emit=(lambda s: jax.tree.map(lambda v: v[::lanes], s)) if record else None)
        final, tally = jax.tree.map(lambda v: v[::lanes], (final, tally))
        robot, episode = finalize(tally, final, params)
        extra_robot, extra_episode = cf.finalize(c, solo, final, episode["makespan"], params)
        return {**robot, **extra_robot}, {**episode, **extra_episode}, out, state

    @jax.jit
    def run(key: jax.Array, params: EnvParams) -> tuple:
        k_reset, k_steps = jax.random.split(key)
        reset_keys = jax.random.split(k_reset, num_episodes)
        step_keys = jax.random.split(k_steps, num_steps)
        if counterfactual:
            robot, episode, states, first = run_counterfactual(reset_keys, step_keys, params)
            first = jax.tree.map(lambda v: v[::1 + num_robots], first)
        else:
            obs, first = reset(reset_keys, params)
            final, tally, _, states = play(params, obs, first, 1, step_keys,
                                           emit=(lambda s: s) if record else None)
            robot, episode = finalize(tally, final, params)
        values = jax.vmap(metrics.per_episode)(robot, episode)
        if record:
            states = jax.tree.map(lambda a, rest: jnp.concatenate([a[None], rest]), first, states)
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
    record: bool = False, counterfactual: bool = False,
) -> Episodes:
    """Play ``num_episodes`` episodes at once and return their metrics on the host
    (``counterfactual``: with the counterfactual lanes and metrics, :func:`episode_runner`)."""
    if num_episodes < 1:
        raise ValueError(f"num_episodes must be at least 1, got {num_episodes}")
    env.check_params(params)
    run = episode_runner(env, params, load_policy(policy, env), num_episodes, constants, record,
                         counterfactual)
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


def steps_played(episodes: Episodes, params: EnvParams) -> int:
    """Steps a batch ran: its longest episode, rounded up to the runner's chunk of steps (at
    most the time limit)."""
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
    baselines and policy objects are unaffected)."""
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
            env, by_count = policy_environment(scenario, num_agents, policy, by_policy[p])
            params = by_count[num_agents[0]]
            run = episode_runner(env, params, load_policy(policy, env, deterministic), episodes,
                                 constants, counterfactual=counterfactual)
            compiled = run.lower(key, params).compile()
            compile_seconds = time.perf_counter() - t0
            for n in num_agents:
                params = by_count[n]
                batch = _play(compiled, key, params, compile_seconds)
                result = ConfigResult(
                    scenario=str(scenario), policy=name, num_agents=n, episodes=episodes,
                    seed=seed, dt=float(params.dt), max_steps=int(params.max_steps),
                    metrics=summarize_episodes(batch), seconds=time.perf_counter() - t0,
                    compile_seconds=batch.compile_seconds, run_seconds=batch.run_seconds,
                    counterfactual=counterfactual, steps_played=steps_played(batch, params))
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
