"""Throughput of the evaluation runner: with the counterfactual lanes, with the metrics, and
without the metric accumulators.

``sgjax.evaluation.runner.EpisodeRunner`` plays a batch of episodes as
``jit(scan(vmap(step_env)))``, freezing ended episodes and updating
``sgjax.evaluation.metrics`` every step. This prints agent-steps/s over the whole time limit (of
the evaluated episodes themselves), compile time and peak memory (XLA's memory analysis) for:
the runner with the counterfactual lanes on (each robot alone and the episode without each
robot: ``1 + 2R`` lanes per episode, ``sgjax.evaluation.counterfactual``), the plain runner,
the same loop with no metrics (the same kernel, ``scan_until_done``), all three stepping
through the whole time limit; and the plain runner as ``sgjax evaluate`` runs it, stopping once
every episode has ended ("early stop": its rate is time-limit agent-steps per second of the
same evaluation, so it shows the saving).

    python bench/evaluation.py --episodes 256 1024 --robots 4 10
"""

from __future__ import annotations

import argparse
import time

import jax
from compiled import compile_measured

import sgjax
from sgjax.evaluation import metrics
from sgjax.evaluation.policies import only_local
from sgjax.evaluation.runner import EpisodeRunner, scan_until_done


def without_metrics(env, params, policy, num_episodes: int):
    """The runner's loop (freeze on end included) with the metric update replaced by nothing
    but the episode-done flag."""
    steps = int(params.max_steps)
    reset = jax.vmap(env.reset, in_axes=(0, None))
    step = jax.vmap(env.step_env, in_axes=(0, 0, 0, None))
    act = jax.vmap(policy, in_axes=(0, 0, 0, None))
    done_of = jax.vmap(metrics.episode_done)

    def one_step(carry, key):
        obs, state, running = carry
        k_act, k_step = jax.random.split(key)
        actions = act(obs, jax.random.split(k_act, num_episodes), state, params)
        nobs, nstate, _, term, trunc, _ = step(jax.random.split(k_step, num_episodes), state,
                                               actions, params)

        def keep(new, old):
            return jax.numpy.where(running.reshape((-1,) + (1,) * (new.ndim - 1)), new, old)

        done = done_of(nstate, term, trunc)
        return keep(nobs, obs), jax.tree.map(keep, nstate, state), running & ~done

    @jax.jit
    def run(key):
        obs, state = reset(jax.random.split(key, num_episodes), params)
        running = jax.numpy.ones(num_episodes, bool)
        (_, state, running), _, _ = scan_until_done(
            one_step, (obs, state, running), lambda c: ~jax.numpy.any(c[2]), steps, steps,
            xs=jax.random.split(key, steps), stop_early=False)
        return state.time, running

    return run


def measure(run, repeats: int) -> tuple[float, float, float]:
    """(compile s, best run s, peak MB)."""
    key = jax.random.key(0)
    compiled, compile_s, peak_bytes = compile_measured(run.lower(key))
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(key))
        best = min(best, time.perf_counter() - t0)
    return compile_s, best, peak_bytes / 2**20


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default="doorway")
    parser.add_argument("--episodes", nargs="+", type=int, default=[256, 1024])
    parser.add_argument("--robots", nargs="+", type=int, default=[4, 10])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print(f"jax {jax.__version__} on {jax.devices()[0].platform}, {args.scenario}, "
          f"only_local, one time limit per run")
    print(f"{'robots':>6}{'episodes':>9}{'variant':>16}{'agent-steps/s':>15}{'compile s':>11}"
          f"{'peak MB':>9}")
    for robots in args.robots:
        env, params = sgjax.make(args.scenario, num_agents=robots)
        steps = int(params.max_steps)
        for episodes in args.episodes:
            policy = only_local(env)
            with_metrics = EpisodeRunner(env, policy, episodes, steps, stop_early=False).episodes
            lanes = EpisodeRunner(env, policy, episodes, steps, counterfactual=True,
                                  stop_early=False).episodes
            early = EpisodeRunner(env, policy, episodes, steps).episodes
            runs = {"counterfactual": jax.jit(lambda key, run=lanes, p=params: run(key, p)),
                    "with metrics": jax.jit(lambda key, run=with_metrics, p=params: run(key, p)),
                    "no metrics": without_metrics(env, params, only_local(env), episodes),
                    "early stop": jax.jit(lambda key, run=early, p=params: run(key, p))}
            for name, run in runs.items():
                compile_s, best, peak = measure(run, args.repeats)
                rate = steps * episodes * robots / best
                print(f"{robots:>6}{episodes:>9}{name:>16}{rate:>15,.0f}{compile_s:>11.1f}"
                      f"{peak:>9.1f}", flush=True)


if __name__ == "__main__":
    main()
