"""Steps per second seen by Stable-Baselines3: the SuperSuit route vs sgjax's native VecEnv.

Both are stepped through the SB3 ``VecEnv`` API with random actions (numpy in, numpy out), and
PPO's own collection + update rate is measured for each. Needs ``pip install torch==2.13.0``
then ``pip install -e ".[sb3]"``.

    python bench/sb3_vecenv.py --scenario doorway --num-agents 4
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from sgjax.adapters.sb3 import SgjaxVecEnv, supersuit_vec_env


def vec_steps_per_second(venv, steps: int) -> float:
    """Agent-steps/s (SB3 slots x steps / s) with random actions, after a warm-up."""
    venv.reset()
    rng = np.random.default_rng(0)

    def actions():  # GO (0) or STOP (1) per slot
        return rng.integers(0, 2, venv.num_envs)

    for _ in range(3):
        venv.step(actions())
    t0 = time.perf_counter()
    for _ in range(steps):
        venv.step(actions())
    return venv.num_envs * steps / (time.perf_counter() - t0)


def ppo_steps_per_second(venv, total: int) -> float:
    from stable_baselines3 import PPO

    model = PPO("MlpPolicy", venv, n_steps=max(16, 2048 // venv.num_envs), batch_size=256)
    model.learn(venv.num_envs * 4)  # warm-up (compiles the jitted step)
    t0 = time.perf_counter()
    model.learn(total)
    return total / (time.perf_counter() - t0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default="doorway")
    parser.add_argument("--num-agents", type=int, default=4)
    parser.add_argument("--num-envs", type=int, nargs="+", default=[1, 16, 64, 256])
    args = parser.parse_args()
    torch.set_num_threads(1)
    print(f"{args.scenario}, {args.num_agents} robots per environment, GO/STOP actions; "
          f"agent-steps/s through the SB3 VecEnv API")
    print(f"{'route':<34}{'SB3 slots':>10}{'env step':>14}{'PPO learn':>14}")
    ss = supersuit_vec_env(args.scenario, num_agents=args.num_agents)
    print(f"{'SuperSuit (1 environment)':<34}{ss.num_envs:>10}"
          f"{vec_steps_per_second(ss, 200):>14,.0f}{ppo_steps_per_second(ss, 4096):>14,.0f}",
          flush=True)
    for n in args.num_envs:
        native = SgjaxVecEnv(args.scenario, num_agents=args.num_agents, num_envs=n)
        steps = max(20, 20_000 // native.num_envs)
        print(f"{f'native SgjaxVecEnv ({n} environments)':<34}{native.num_envs:>10}"
              f"{vec_steps_per_second(native, steps):>14,.0f}"
              f"{ppo_steps_per_second(native, max(8192, native.num_envs * 64)):>14,.0f}",
              flush=True)


if __name__ == "__main__":
    main()
