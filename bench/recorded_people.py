"""Cost of recorded people: a replayed-pedestrian step against a social-force step at the same
crowd size (issue 68's target: a replayed step costs no more).

For each ETH/UCY scene (``--scenes``, files of ``--data``): the scene as ``recorded:FILE`` with
its people replayed as ghosts, pausing and handed over (``human_replay``), and the same map with
as many simulated Moussaid pedestrians as the recording's slots (``num_humans`` = the most people
a window holds, random goals). Each row is ``jit(scan(env.step_batch))`` over ``--envs``
environments, 4 robots mostly GO (``building_scale.prepare``); agent-steps count robots and
pedestrian slots alike. Rows are compiled first, then timed in turn ``--rounds`` times,
keeping each row's best.

    python bench/recorded_people.py
    python bench/recorded_people.py --scenes crowds_zara01.txt students001.txt --envs 64
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import jax
from building_scale import prepare

import sgjax

DATA = Path(__file__).resolve().parents[2] / "shared" / "pedestrians" / "eth_ucy"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--scenes", nargs="+", default=["crowds_zara01.txt", "students001.txt"])
    parser.add_argument("--robots", type=int, default=4)
    parser.add_argument("--envs", type=int, default=64)
    parser.add_argument("--time-limit", type=float, default=30.0)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    print(f"jax {jax.__version__} on {jax.devices()[0].platform}, {os.cpu_count()} CPU(s); "
          f"{args.robots} robots, {args.envs} envs; load average "
          + " ".join(f"{v:.2f}" for v in os.getloadavg()), flush=True)
    rows = []
    for scene in args.scenes:
        path = args.data / scene
        if not path.is_file():
            raise SystemExit(f"--scenes {scene}: no file {path} (give --data)")
        common = dict(num_agents=args.robots, time_limit=args.time_limit)
        for mode in ("ghost", "pause", "handover"):
            env, params = sgjax.make(f"recorded:{path}", human_replay=mode, **common)
            people = env.config.humans.max_humans
            rows.append((scene, f"replayed ({mode})", people,
                         prepare(env, params, args.robots, args.envs, args.steps)))
        env, params = sgjax.make(f"recorded:{path}", human_replay="off", num_humans=people,
                                 **common)
        rows.append((scene, "simulated (moussaid)", people,
                     prepare(env, params, args.robots, args.envs, args.steps)))
    best = [float("inf")] * len(rows)
    for _ in range(args.rounds):
        for i, row in enumerate(rows):
            best[i] = min(best[i], row[-1][2](args.repeats))
    header = (f"{'scene':<20}{'pedestrians':<24}{'slots':>6}{'agent-steps/s':>15}"
              f"{'compile s':>11}")
    print(header + "\n" + "-" * len(header))
    for (scene, kind, people, (compile_s, _, _)), seconds in zip(rows, best, strict=True):
        rate = args.envs * (args.robots + people) / seconds
        print(f"{scene:<20}{kind:<24}{people:>6}{rate:>15,.0f}{compile_s:>11.1f}")
    print("load average " + " ".join(f"{v:.2f}" for v in os.getloadavg()))


if __name__ == "__main__":
    main()
