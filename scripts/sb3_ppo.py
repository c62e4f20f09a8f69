"""Train Stable-Baselines3 PPO on an sgjax scenario and report success before and after.

    python scripts/sb3_ppo.py --route native --scenario open --steps 40000
    python scripts/sb3_ppo.py --route supersuit --scenario open --steps 4000

Install ``torch==2.13.0`` first, then ``pip install -e ".[sb3]"``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch
from stable_baselines3 import PPO

from sgjax.adapters.sb3 import SgjaxVecEnv, supersuit_vec_env


def success_count(model: PPO, venv, steps: int = 300) -> tuple[int, int]:
    """(robots that reached their goal, robot episodes ended) over ``steps`` steps."""
    obs = venv.reset()
    reached = ended = 0
    for _ in range(steps):
        action, _ = model.predict(obs, deterministic=True)
        obs, _, done, infos = venv.step(action)
        for i in np.flatnonzero(done):
            ended += 1
            reached += int(infos[i].get("is_success", False))
    return reached, ended


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--route", choices=["native", "supersuit"], default="native")
    parser.add_argument("--scenario", default="open")
    parser.add_argument("--num-agents", type=int, default=2)
    parser.add_argument("--num-envs", type=int, default=16, help="native route only")
    parser.add_argument("--action-mode", default="continuous", choices=["continuous", "go_stop"])
    parser.add_argument("--time-limit", type=float, default=15.0)
    parser.add_argument("--steps", type=int, default=40_000)
    args = parser.parse_args()
    torch.set_num_threads(1)  # small machines: torch threads fight JAX's

    common = dict(num_agents=args.num_agents, action_mode=args.action_mode,
                  time_limit=args.time_limit)
    if args.route == "native":
        def make_venv(seed: int):
            return SgjaxVecEnv(args.scenario, num_envs=args.num_envs, seed=seed, **common)
        model = PPO("MlpPolicy", make_venv(0), n_steps=64, batch_size=256, seed=0)
    else:
        def make_venv(seed: int):
            return supersuit_vec_env(args.scenario, **common)
        model = PPO("MlpPolicy", make_venv(0), n_steps=256, batch_size=128)  # no seed=: see docs

    before = success_count(model, make_venv(1))
    t0 = time.perf_counter()
    model.learn(args.steps)
    seconds = time.perf_counter() - t0
    after = success_count(model, make_venv(1))
    print(f"{args.route} route, {args.scenario}: {args.steps} steps in {seconds:.1f} s "
          f"({args.steps / seconds:,.0f} steps/s)")
    print(f"robots reaching their goal: before {before[0]}/{before[1]}, "
          f"after {after[0]}/{after[1]}")


if __name__ == "__main__":
    main()
