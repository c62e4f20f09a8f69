"""One table over every cell of a benchmark: rliable's aggregates for each method.

A benchmark's cells (every scenario at every robot count) each hold a method's team success
per training seed (one value for an untrained method). Reading 25 cells one by one invites
counting wins; the aggregates answer "which method is better overall" with one interval each:

* the **mean** and the **interquartile mean** (IQM: the mean of the middle half of all runs,
  robust to a few cells where everything fails or everything succeeds) of every run of every
  cell, with stratified-bootstrap intervals (seeds resampled within each cell);
* the **probability of improvement** over a reference method: the mean over cells of the
  chance that a random seed of the method beats a random seed of the reference (ties half),
  with its stratified-bootstrap interval (an interval above 0.5 is a method that is better
  more often than not);
* a **performance profile**: the share of runs whose team success exceeds each threshold,
  with a stratified-bootstrap band (in the table at four thresholds; drawn over all of them
  by :func:`plot_performance_profiles`).

The statistics are :mod:`sgjax.evaluation.statistics`' (``aggregate_over_cells``,
``improvement_over_cells``, ``performance_profile``); ``python -m train.reproduce`` writes the
table as ``across_cells.md`` and the profiles as ``performance_profiles.png``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from sgjax.evaluation.report import markdown_table, new_figure
from sgjax.evaluation.statistics import (
    aggregate_over_cells,
    improvement_over_cells,
    performance_profile,
)

THRESHOLDS = (0.25, 0.5, 0.75, 0.9)  # team success levels of the performance profile
RESAMPLES = 2000


Results = Mapping[str, Mapping[str, Mapping[int, Mapping[str, Sequence[float]]]]]
"""``{scenario: {method: {robots: {metric: [per-seed value]}}}}``, as ``results.json`` holds."""


def method_cells(results: Results, counts: Sequence[int], metric: str = "team_success"
                 ) -> dict[str, dict[str, np.ndarray]]:
    """``{method: {"<scenario> <robots>": per-seed values [S]}}`` from a results table
    ``{scenario: {method: {robots: {metric: [S]}}}}`` (cells a method lacks are left out)."""
    cells: dict[str, dict[str, np.ndarray]] = {}
    for scenario, by_method in results.items():
        for method, by_count in by_method.items():
            for n in counts:
                if n in by_count and metric in by_count[n]:
                    cells.setdefault(method, {})[f"{scenario} {n}"] = np.asarray(
                        by_count[n][metric], float)
    return cells


def _interval(mean: float, low: float, high: float, scale: float = 100.0,
              digits: int = 0) -> str:
    return f"{scale * mean:.{digits}f} [{scale * low:.{digits}f}, {scale * high:.{digits}f}]"


def across_cells_table(results: Results, counts: Sequence[int],
                       references: Sequence[str] = ("only_local",),
                       title: str = "Every method over every cell") -> str:
    """The markdown table: per method, its number of cells and runs, mean and IQM team
    success (%), the probability of improvement over each of ``references`` present in the
    results (over the cells both have), and its performance profile at :data:`THRESHOLDS`.
    Intervals are 95% stratified-bootstrap percentile intervals (:data:`RESAMPLES`)."""
    cells = method_cells(results, counts)
    references = [r for r in references if r in cells]
    rows = []
    for method, mine in cells.items():
        agg = aggregate_over_cells(mine, resamples=RESAMPLES)
        better = []
        for reference in references:
            if reference == method:
                better.append("")
                continue
            p = improvement_over_cells(mine, cells[reference], resamples=RESAMPLES)
            better.append(_interval(p["probability"], p["low"], p["high"], 1.0, 2))
        profile = performance_profile(mine, np.asarray(THRESHOLDS), resamples=RESAMPLES)
        shares = [_interval(f, lo, hi) for f, lo, hi in
                  zip(profile["fraction"], profile["low"], profile["high"], strict=True)]
        runs = sum(v.size for v in mine.values())
        rows.append([method, str(len(mine)), str(runs),
                     _interval(agg["mean"], agg["mean_low"], agg["mean_high"]),
                     _interval(agg["iqm"], agg["iqm_low"], agg["iqm_high"]), *better, *shares])
    caption = (
        "Each method over the cells it played (scenario x robot count: "
        f"{', '.join(map(str, counts))} robots), every run counted (a trained method's "
        "training seeds, an untrained method's one evaluation): the mean and the "
        "interquartile mean (IQM) of their team success (%); P(> reference): the probability "
        "that a random run of the method beats a random run of the reference in a cell (ties "
        "half), averaged over the cells both played (above 0.5: better more often than not); "
        "runs above t: the share of runs (%) whose team success exceeds t (the performance "
        "profile). All [95% stratified-bootstrap intervals, runs resampled within each cell, "
        f"{RESAMPLES:,} resamples] (rliable's aggregates). An untrained method has one run "
        "per cell, so nothing of its own to resample: its interval is a point (the paired "
        "tables cell by cell carry the episodes' spread).")
    text = [f"# {title} (team success)", "", caption, "",
            *markdown_table(["Method", "Cells", "Runs", "Mean (%)", "IQM (%)",
                             *(f"P(> {r})" for r in references),
                             *(f"Runs above {t:g} (%)" for t in THRESHOLDS)], rows)]
    return "\n".join(text) + "\n"


def plot_performance_profiles(results: Results, counts: Sequence[int], path: Path,
                              title: str = "Performance profiles over every cell") -> Path:
    """Each method's performance profile (the share of its runs, over every cell, whose team
    success exceeds t, for t from 0 to 1) with its 95% stratified-bootstrap band, into the PNG
    ``path`` (rliable's performance-profile plot)."""
    cells = method_cells(results, counts)
    thresholds = np.linspace(0.0, 1.0, 41)
    fig = new_figure(6.4, 4.0)
    ax = fig.subplots()
    for index, (method, mine) in enumerate(cells.items()):
        profile = performance_profile(mine, thresholds, resamples=RESAMPLES // 4)
        colour = f"C{index % 10}"
        ax.plot(thresholds, 100 * profile["fraction"], color=colour, label=method)
        ax.fill_between(thresholds, 100 * profile["low"], 100 * profile["high"], color=colour,
                        alpha=0.2, linewidth=0)
    ax.set_xlabel("team success t", fontsize=8)
    ax.set_ylabel("runs with team success above t (%)", fontsize=8)
    ax.set_title(title, fontsize=9)
    ax.set_xlim(0.0, 1.0)
    ax.set_ylim(-2, 102)
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    return path
