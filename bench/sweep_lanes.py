"""A sweep's wall time with trials as lanes against one trial at a time, back to back.

Runs ``python -m train.sweep`` twice on the same config and space, each in a fresh study and
run folder: once with the space's lanes (or ``--lanes``), once with one lane (one trial at a
time, the same compiled program shape otherwise), and prints each run's wall time, its phases
(from ``sweep.json``), trials per hour, the trials' states and the speed-up. The space's
``trial.seeds`` must be 1 for the one-lane run to be one trial at a time.

    python bench/sweep_lanes.py --config train/configs/doorway.yaml \\
        --space train/configs/sweeps/doorway.yaml --out runs/bench-sweep

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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", required=True)
    parser.add_argument("--space", required=True)
    parser.add_argument("--out", default="runs/bench-sweep")
    parser.add_argument("--lanes", type=int, default=None,
                        help="lanes of the batched run (default: the space's)")
    args, extra = parser.parse_known_args()
    extra = [a for a in extra if a != "--"]
    out = Path(args.out)
    batched = ["--lanes", str(args.lanes)] if args.lanes else []
    lanes = args.lanes
    if lanes is None:
        from train.search_space import load_space
        lanes = load_space(args.space).lanes
    rows = [run(args.config, args.space, out / f"lanes-{lanes}", lanes, extra + batched[2:]),
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
