"""A sweep's wall time with trials as lanes against one trial at a time, back to back.

Runs ``python -m train.sweep`` twice on the same config and space, each in a fresh study and
run folder: once with the space's lanes (or ``--lanes``), once with one lane (one trial at a
time, the same compiled program shape otherwise), and prints each run's wall time, its phases
(from ``sweep.json``), trials per hour, the trials' states and the speed-up. The space's
``trial.seeds`` must be 1 for the one-lane run to be one trial at a time.

    python bench/sweep_lanes.py --config train/configs/doorway.yaml \\
        --space train/configs/sweeps/doorway.yaml --out runs/bench-sweep

``--per-update 1 4 8`` instead times one compiled update of that many lanes of the space's
first group (two updates after compiling), per lane: the cost of a lane against a trial alone.

Extra arguments after ``--`` go to both sweeps (``-- --set algorithm.total_steps=2e5``;
``-- --pruner none`` makes both runs train every trial to the end, the like-for-like
comparison: with a pruner, one trial at a time prunes earlier, as five trials have finished
before the sixth starts).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

from sgjax.evaluation.provenance import cpu_model


def run(config: str, space: str, out: Path, lanes: int, extra: list[str]) -> dict:
    command = [sys.executable, "-m", "train.sweep", "--config", config, "--space", space,
               "--out", str(out), "--lanes", str(lanes), "--study", f"lanes-{lanes}",
               "--no-progress", *extra]
    print("$ " + " ".join(command[1:]), flush=True)
    start = time.perf_counter()
    subprocess.run(command, check=True)
    wall = time.perf_counter() - start
    document = json.loads((out / "sweep.json").read_text())
    states: dict[str, int] = {}
    for trial in document["trials"]:
        if not trial["user_attrs"].get("surplus"):
            states[trial["state"]] = states.get(trial["state"], 0) + 1
    return {"lanes": lanes, "wall": wall, "states": states,
            "seconds": document["provenance"].get("seconds", {}),
            "best": document["best"]["value"] if document["best"] else None}


def per_update(config: str, space_path: str, counts: list[int], sets: list[str]) -> None:
    """Seconds per update of ``count`` lanes (best of 3 calls of 2 updates, after compiling)."""
    import jax

    from train.algorithm.config import load_config
    from train.run.search_space import load_space
    from train.sweep import Group, with_values

    space = load_space(space_path)
    data = with_values(load_config(config, sets).to_dict(), dict(space.settings))
    print(f"machine: {cpu_model()}")
    for count in counts:
        group = Group(data, {}, space.replace(lanes=count * space.seeds), count * space.seeds,
                      "bench")
        group.per_chunk = 2
        group._chunk = group.trainer.jitted_chunk_lanes(2, donate=True)
        runners = group.start()
        runners, _ = group.advance(runners)
        jax.block_until_ready(runners.steps)
        times = []
        for _ in range(3):
            start = time.perf_counter()
            runners, _ = group.advance(runners)
            jax.block_until_ready(runners.steps)
            times.append((time.perf_counter() - start) / 2)
        lanes = count * space.seeds
        steps = group.config.algorithm.steps_per_update * lanes / min(times)
        print(f"lanes {lanes}: compile {group.compile_s:.1f} s, {min(times):.2f} s per update "
              f"of all lanes, {min(times) / lanes:.3f} s per lane-update, {steps:,.0f} "
              "env-steps/s", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", required=True)
    parser.add_argument("--space", required=True)
    parser.add_argument("--out", default="runs/bench-sweep")
    parser.add_argument("--lanes", type=int, default=None,
                        help="lanes of the batched run (default: the space's)")
    parser.add_argument("--per-update", type=int, nargs="+", default=None, metavar="LANES",
                        help="time one update of these lane counts instead of two sweeps")
    args, extra = parser.parse_known_args()
    extra = [a for a in extra if a != "--"]
    if args.per_update:
        sets = [extra[i + 1] for i, a in enumerate(extra) if a == "--set"]
        per_update(args.config, args.space, args.per_update, sets)
        return
    out = Path(args.out)
    lanes = args.lanes
    if lanes is None:
        from train.run.search_space import load_space
        lanes = load_space(args.space).lanes
    rows = [run(args.config, args.space, out / f"lanes-{lanes}", lanes, extra),
            run(args.config, args.space, out / "lanes-1", 1, extra)]
    print(f"\nmachine: {cpu_model()}")
    print("| lanes | wall (s) | trials/hour | trials | best | phases (s) |")
    print("|---|---|---|---|---|---|")
    for row in rows:
        count = sum(row["states"].values())
        phases = ", ".join(f"{k} {v:.0f}" for k, v in row["seconds"].items())
        states = ", ".join(f"{n} {s}" for s, n in sorted(row["states"].items()))
        best = "" if row["best"] is None else f"{row['best']:.3f}"
        print(f"| {row['lanes']} | {row['wall']:.0f} | {3600 * count / row['wall']:.1f} | "
              f"{states} | {best} | {phases} |")
    print(f"\nspeed-up of {lanes} lanes over one trial at a time: "
          f"{rows[1]['wall'] / rows[0]['wall']:.2f}x")


if __name__ == "__main__":
    main()
