"""Learning curves of training runs, drawn from their ``progress.csv`` files.

    python -m train.reports.curves runs/intersection   # -> runs/intersection/learning_curve.png
    python -m train.reports.curves runs/seed0 runs/seed1 --out seeds.png   # several runs

Three panels over environment steps: success (the team and robot success of the training
episodes that ended in each chunk of updates, lines; the periodic evaluation's team success,
points: ``evaluation.episodes`` episodes at the curriculum's robot count of that moment), the
mean return per robot of those training episodes, and the policy's entropy (nats). ``python -m
train`` draws its run's curve when training ends.
"""

from __future__ import annotations

import argparse
import csv
import math
from collections.abc import Sequence
from pathlib import Path

from sgjax.evaluation.report import new_figure

NEEDED = ("steps", "team_success", "robot_success", "mean_return", "entropy",
          "eval_team_success")


def progress_file(run: Path) -> Path:
    """The ``progress.csv`` of a run folder, or ``run`` itself when it names the file."""
    return run / "progress.csv" if run.is_dir() else run


def read_progress(path: Path) -> dict[str, list[float]]:
    """The columns of a ``progress.csv`` as floats (NaN where a row left a value empty, as the
    evaluation columns are between evaluations). ValueError naming the file when it has no rows
    or lacks a column the curves need."""
    if not path.is_file():
        raise ValueError(f"{path}: no such run folder or progress.csv (python -m train writes "
                         "one into its run folder)")
    with path.open(newline="") as file:
        rows = list(csv.DictReader(file))
    if not rows:
        raise ValueError(f"{path}: no rows yet (the run logs one per chunk of updates)")
    missing = [name for name in NEEDED if name not in rows[0]]
    if missing:
        raise ValueError(f"{path}: no column {', '.join(missing)} (columns: "
                         f"{', '.join(rows[0])})")
    columns: dict[str, list[float]] = {}
    for name in rows[0]:
        try:
            columns[name] = [float(row[name]) if row[name] not in ("", None) else math.nan
                             for row in rows]
        except ValueError as error:
            raise ValueError(f"{path}: column {name}: {error}") from None
    return columns


def plot_learning_curves(runs: Sequence[Path], path: Path,
                         labels: Sequence[str] | None = None) -> Path:
    """Draw the learning curves of ``runs`` (run folders or ``progress.csv`` files) into the PNG
    ``path``; each run in its own colour, labelled by ``labels`` (default: folder names)."""
    if not runs:
        raise ValueError("plot_learning_curves: no runs given")
    files = [progress_file(run) for run in runs]
    labels = list(labels) if labels is not None else [f.parent.name for f in files]
    if len(labels) != len(files):
        raise ValueError(f"plot_learning_curves: {len(labels)} labels for {len(files)} runs")
    fig = new_figure(13, 3.6)
    ax_success, ax_return, ax_entropy = fig.subplots(1, 3)
    several = len(files) > 1
    for index, (file, label) in enumerate(zip(files, labels, strict=True)):
        columns = read_progress(file)
        steps = columns["steps"]
        colour = f"C{index % 10}"
        prefix = f"{label}: " if several else ""
        ax_success.plot(steps, columns["team_success"], color=colour,
                        label=f"{prefix}training episodes, team")
        ax_success.plot(steps, columns["robot_success"], color=colour, linestyle=":",
                        label=f"{prefix}training episodes, robot")
        evaluated = [(s, v) for s, v in zip(steps, columns["eval_team_success"], strict=True)
                     if not math.isnan(v)]
        if evaluated:
            ax_success.plot(*zip(*evaluated, strict=True), color=colour, marker="o",
                            linestyle="--", label=f"{prefix}periodic evaluation, team")
        ax_return.plot(steps, columns["mean_return"], color=colour, label=label)
        ax_entropy.plot(steps, columns["entropy"], color=colour, label=label)
    ax_success.set_ylim(-0.05, 1.05)
    for ax, title in ((ax_success, "success"), (ax_return, "mean return per robot"),
                      (ax_entropy, "policy entropy (nats)")):
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("environment steps", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    ax_success.legend(fontsize=6)
    if several:
        ax_return.legend(fontsize=6)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    return path


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m train.reports.curves",
        description="Draw the learning curves of training runs from their progress.csv.")
    parser.add_argument("runs", nargs="+", type=Path,
                        help="run folders (or progress.csv files) of python -m train")
    parser.add_argument("--out", type=Path, default=None,
                        help="PNG to write (default with one run: <run>/learning_curve.png; "
                             "required with several)")
    args = parser.parse_args(argv)
    if args.out is None and len(args.runs) > 1:
        parser.error("--out: required when drawing several runs")
    out = args.out or progress_file(args.runs[0]).parent / "learning_curve.png"
    try:
        print(f"wrote {plot_learning_curves(args.runs, out)}")
    except ValueError as error:
        parser.error(str(error))


if __name__ == "__main__":
    main()
