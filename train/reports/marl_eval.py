"""Export ``train.reproduce``'s results.json in marl-eval's raw-data format.

marl-eval (InstaDeep's aggregation and plotting tools, built on rliable, read by BenchMARL and
Mava) takes one JSON document::

    {env: {task: {algorithm: {run: {"step_1": {"step_count": int, metric: [values]},
                                    "absolute_metrics": {metric: [values]}}}}}}

Here ``env`` is ``sgjax`` (``sgjax-socialgym`` for that profile), a task is a mini-game at a
robot count (``doorway_4robots``), an algorithm a baseline, a run a training seed
(``seed_0``...). sgjax evaluates each trained policy once, at the end of training, so each run
has one step (``step_count`` = the training steps) and ``absolute_metrics`` holds the same
evaluation. ``team_success`` is per episode (the evaluation's shared episodes, in order); every
other metric is the seed's mean over episodes (a one-element list, as marl-eval takes for a
rate). marl-eval needs every algorithm to have the same runs: an untrained baseline (Only Local)
does not depend on the seed, so each run repeats its values on the same first ``episodes``
episodes that the trained seeds played.

    python -m train.reports.marl_eval runs/reproduce/results.json \
        --out runs/reproduce/marl_eval.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

PER_EPISODE = "team_success_by_episode"


def _runs(cell: dict[str, Any], seeds: int, episodes: int, step_count: int,
          untrained: bool) -> dict[str, Any]:
    """One baseline at one robot count -> ``{seed_i: {"step_1": ..., "absolute_metrics": ...}}``
    (an untrained baseline's single evaluation repeated for each of ``seeds``)."""
    by_episode = cell.get(PER_EPISODE)
    runs = {}
    for i in range(seeds):
        row = 0 if untrained else i
        metrics: dict[str, list[float]] = {}
        if by_episode is not None:
            metrics["team_success"] = [float(v) for v in by_episode[row][:episodes]]
        for name, values in cell.items():
            if name == PER_EPISODE or name in metrics:
                continue
            value = values[row]
            metrics[name] = [float("nan") if value is None else float(value)]
        runs[f"seed_{i}"] = {"step_1": {"step_count": step_count, **metrics},
                             "absolute_metrics": metrics}
    return runs


def to_marl_eval(document: dict[str, Any]) -> dict[str, Any]:
    """The marl-eval raw-data document of a reproduce ``results.json`` (parsed)."""
    seeds, episodes = int(document["seeds"]), int(document["episodes"])
    env = "sgjax" if document.get("profile", "sgjax") == "sgjax" else (
        f"sgjax-{document['profile']}")
    tasks: dict[str, dict[str, Any]] = {}
    for scenario, baselines in document["results"].items():
        for baseline, counts in baselines.items():
            for count, cell in counts.items():
                untrained = len(cell.get("team_success", [])) == 1 and seeds > 1
                steps = 0 if untrained else int(document.get("total_steps") or 0)
                tasks.setdefault(f"{scenario}_{count}robots", {})[baseline] = _runs(
                    cell, seeds, episodes, steps, untrained)
    return {env: tasks}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="results.json -> marl-eval raw data JSON")
    parser.add_argument("results", help="a train.reproduce results.json")
    parser.add_argument("--out", required=True, help="the marl-eval JSON to write")
    args = parser.parse_args(argv)
    document = json.loads(Path(args.results).read_text())
    if "results" not in document or "seeds" not in document:
        raise SystemExit(f"{args.results}: not a train.reproduce results.json (no 'results' "
                         "and 'seeds')")
    Path(args.out).write_text(json.dumps(to_marl_eval(document), indent=1) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
