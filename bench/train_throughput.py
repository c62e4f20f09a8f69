"""Training throughput: environment plus learning, in agent-steps per second.

Times whole PPO updates (rollout with auto-reset, GAE, epochs of minibatches) of
``train.ppo.Trainer`` on the doorway for several batch sizes and robot counts, and prints
agent-steps/s, env-steps/s, compile time and peak memory (XLA's memory analysis of the
compiled chunk of updates).

    python bench/train_throughput.py --num-envs 64 256 1024 --robots 4 10
"""

from __future__ import annotations

import argparse
import time

import jax

from train.config import config_from_dict
from train.ppo import Trainer


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default="doorway")
    parser.add_argument("--num-envs", nargs="+", type=int, default=[64, 256, 1024])
    parser.add_argument("--robots", nargs="+", type=int, default=[4, 10])
    parser.add_argument("--updates", type=int, default=4, help="updates per timed call")
    parser.add_argument("--network", default="mlp", choices=["mlp", "gru"])
    args = parser.parse_args()
    print(f"jax {jax.__version__} on {jax.devices()[0].platform}, {args.scenario}, IPPO "
          f"{args.network}, 64 steps x 4 epochs x 4 minibatches per update")
    print(f"{'robots':>6}{'envs':>7}{'agent-steps/s':>15}{'env-steps/s':>13}{'compile s':>11}"
          f"{'peak MB':>9}")
    for robots in args.robots:
        for envs in args.num_envs:
            config = config_from_dict({
                "env": {"scenarios": [args.scenario], "curriculum": [[0, robots]]},
                "algorithm": {"num_envs": envs, "num_steps": 64, "total_steps": 10**8},
                "network": {"kind": args.network}})
            trainer = Trainer(config)
            runner = jax.jit(trainer.init)(jax.random.PRNGKey(0))
            chunk = jax.jit(lambda r, t=trainer: t.update_chunk(r, args.updates))
            t0 = time.perf_counter()
            compiled = chunk.lower(runner).compile()
            compile_s = time.perf_counter() - t0
            mem = compiled.memory_analysis()
            peak = 0.0 if mem is None else (mem.argument_size_in_bytes + mem.output_size_in_bytes
                                            + mem.temp_size_in_bytes) / 2**20
            runner, _ = compiled(runner)  # warm
            jax.block_until_ready(runner.params)
            best = float("inf")
            for _ in range(2):
                t0 = time.perf_counter()
                runner, _ = compiled(runner)
                jax.block_until_ready(runner.params)
                best = min(best, time.perf_counter() - t0)
            env_rate = args.updates * 64 * envs / best
            print(f"{robots:>6}{envs:>7}{env_rate * robots:>15,.0f}{env_rate:>13,.0f}"
                  f"{compile_s:>11.1f}{peak:>9.1f}", flush=True)


if __name__ == "__main__":
    main()
