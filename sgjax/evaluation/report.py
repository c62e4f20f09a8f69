"""Evaluation outputs: ``metrics.json``, ``metrics.csv``, ``table.md`` and PNG charts.

``table.md`` follows the SocialGym 2.0 paper's two tables (its Tables 3 and 4): the headline
metrics per scenario, policy and robot count, and team success (%) by robot count with the
average; then every metric of every configuration with its 95% interval.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from sgjax.evaluation.metrics import METRICS, MetricConstants
from sgjax.evaluation.result_schema import EVALUATE
from sgjax.evaluation.statistics import CONFIDENCE, ConfigResult, Summary
from sgjax.files import write_atomic
from sgjax.version import __version__

if TYPE_CHECKING:  # matplotlib is imported where a figure is drawn (half a second at start-up)
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

# The paper's Table 3 columns, then success.
HEADLINE = (("episode_length", "Avg. length (steps)"), ("collisions", "Coll. rate"),
            ("stop_time", "Stop time (s)"), ("velocity_change_max", "Max dV (m/s)"),
            ("team_success", "Team success"), ("success", "Robot success"))
# The multi-robot mini-game metrics (SMGLib's, made exact), the counterfactual ones when run.
MINI_GAME = (("makespan", "Makespan (s)"), ("flow_rate", "Flow (1/(m s))"))
MINI_GAME_COUNTERFACTUAL = (
    ("makespan_ratio", "Makespan ratio"), ("path_deviation_mean", "Path dev. (m)"),
    ("hausdorff", "Hausdorff (m)"), ("invasiveness_robots", "Invasive, robots (m)"),
    ("invasiveness_humans", "Invasive, people (m)"), ("invasiveness_speed", "Invasive (m/s)"))
CHARTED = ("team_success", "success", "collisions", "episode_length", "stop_time",
           "velocity_change_max", "min_distance_robot", "spl", "deadlock")


def write_all(results: Sequence[ConfigResult], out: Path,
              constants: MetricConstants, provenance: dict | None = None) -> list[Path]:
    """Write every output into ``out`` (created); returns the paths written. ``provenance``
    (:func:`sgjax.evaluation.provenance.provenance`) goes into ``metrics.json``."""
    out.mkdir(parents=True, exist_ok=True)
    return [write_json(results, out / "metrics.json", constants, provenance),
            write_csv(results, out / "metrics.csv"),
            write_table(results, out / "table.md"),
            plot_success(results, out / "success_by_robots.png"),
            plot_metrics(results, out / "metrics_by_robots.png")]


def write_json(results: Sequence[ConfigResult], path: Path, constants: MetricConstants,
               provenance: dict | None = None) -> Path:
    document = {
        "schema_version": EVALUATE,
        "sgjax_version": __version__,
        **({} if provenance is None else {"provenance": provenance}),
        "confidence": CONFIDENCE,
        "interval": "Wilson score for yes/no episode metrics (binary), Student t otherwise, "
                    "clipped to [0, 1] for fractions and at 0 below; "
                    "over episodes, NaN values (metric undefined) left out",
        "constants": constants.as_dict(),
        "definitions": {m.name: {"unit": m.unit, "level": m.level, "reduce": m.reduce,
                                 "binary": m.binary, "definition": m.definition,
                                 "source": m.source} for m in METRICS},
        "results": [r.as_dict() for r in results],
    }
    write_atomic(path, json.dumps(document, indent=1))
    return path


def write_csv(results: Sequence[ConfigResult], path: Path) -> Path:
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["scenario", "policy", "num_agents", "episodes", "metric", "unit",
                         "mean", "ci_low", "ci_high", "std", "n"])
        for r in results:
            for name, s in r.metrics.items():
                d = s.as_dict()
                writer.writerow([r.scenario, r.policy, r.num_agents, r.episodes, name,
                                 METRICS[name].unit,
                                 *("" if d[k] is None else d[k]
                                   for k in ("mean", "ci_low", "ci_high", "std", "n"))])
    return path


def format_points(mean: float, low: float | None, high: float | None) -> str:
    """A difference of two shares in percentage points with its interval: ``"+12 [+3, +21]"``,
    or ``"+12"`` where there is no interval (``low`` None or NaN: one pair)."""
    if low is None or high is None or math.isnan(low):
        return f"{100 * mean:+.0f}"
    return f"{100 * mean:+.0f} [{100 * low:+.0f}, {100 * high:+.0f}]"


def format_summary(s: Summary, percent: bool = False) -> str:
    """``"mean ± half-width"`` of a summary (``n/a`` without values), optionally in %."""
    if s.n == 0 or math.isnan(s.mean):
        return "n/a"
    scale = 100.0 if percent else 1.0
    digits = 0 if percent else (0 if abs(s.mean) >= 100 else 2)
    text = f"{s.mean * scale:.{digits}f}"
    if not math.isnan(s.ci_low):
        half = max(s.mean - s.ci_low, s.ci_high - s.mean) * scale
        text += f" ± {half:.{digits}f}"
    return text


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """The lines of a markdown table: ``header``, the rule, then one line per row."""
    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(str(c) for c in cells) + " |"
    return [line(header), "|" + "---|" * len(header), *(line(r) for r in rows)]


def summary_tables(results: Sequence[ConfigResult]) -> str:
    """The paper's two tables as markdown: the headline metrics of every configuration, then
    team success (%) by robot count with the average."""
    lines = [f"Means over episodes ± the larger half of the {CONFIDENCE:.0%} interval; "
             "definitions in docs/metrics.md.", "", "## Metrics per scenario and policy", ""]
    lines += markdown_table(
        ["Scenario", "Policy", "Robots", "Episodes", *(title for _, title in HEADLINE)],
        [[r.scenario, r.policy, r.num_agents, r.episodes,
          *(format_summary(r.metrics[name]) for name, _ in HEADLINE)] for r in results])
    counts = sorted({r.num_agents for r in results})
    rows = []
    for scenario, policy in dict.fromkeys((r.scenario, r.policy) for r in results):
        by_count = {r.num_agents: r.metrics["team_success"] for r in results
                    if (r.scenario, r.policy) == (scenario, policy)}
        means = [s.mean for s in by_count.values() if s.n]
        average = f"{100 * sum(means) / len(means):.0f}" if means else "n/a"
        rows.append([scenario, policy, *(format_summary(by_count[n], percent=True)
                                         if n in by_count else "" for n in counts), average])
    lines += ["", "## Team success (%) by robot count", ""]
    lines += markdown_table(["Scenario", "Policy", *(f"{n}A" for n in counts), "Avg."], rows)
    columns = MINI_GAME + (MINI_GAME_COUNTERFACTUAL if any(r.counterfactual for r in results)
                           else ())
    lines += ["", "## Multi-robot mini-game metrics", ""]
    if not any(r.counterfactual for r in results):
        lines += ["(Path deviation, Hausdorff distance, makespan ratio and invasiveness need "
                  "the counterfactual lanes: `sgjax evaluate --counterfactual`.)", ""]
    lines += markdown_table(
        ["Scenario", "Policy", "Robots", *(title for _, title in columns)],
        [[r.scenario, r.policy, r.num_agents, *(format_summary(r.metrics[name])
                                                 for name, _ in columns)] for r in results])
    return "\n".join(lines)


def write_table(results: Sequence[ConfigResult], path: Path) -> Path:
    lines = [f"# Evaluation (sgjax {__version__})", "", summary_tables(results), "",
             "## Every metric", ""]
    for r in results:
        lines += [f"### {r.scenario}, {r.policy}, {r.num_agents} robots ({r.episodes} episodes,"
                  f" seed {r.seed})", ""]
        rows = []
        for name, s in r.metrics.items():
            interval = ("n/a" if math.isnan(s.ci_low) else f"[{s.ci_low:.3g}, {s.ci_high:.3g}]")
            mean = "n/a" if math.isnan(s.mean) else f"{s.mean:.3g}"
            rows.append([name, METRICS[name].unit, mean, interval, s.n])
        lines += markdown_table(["Metric", "Unit", "Mean", "95% interval", "n"], rows)
        lines.append("")
    path.write_text("\n".join(lines) + "\n")
    return path


def _series(results: Sequence[ConfigResult], metric: str):
    for scenario, policy in dict.fromkeys((r.scenario, r.policy) for r in results):
        rows = sorted((r for r in results if (r.scenario, r.policy) == (scenario, policy)),
                      key=lambda r: r.num_agents)
        s = [r.metrics[metric] for r in rows]
        yield (f"{scenario} / {policy}", [r.num_agents for r in rows], [x.mean for x in s],
               [[max(0.0, x.mean - x.ci_low) if x.n > 1 else 0.0 for x in s],
                [max(0.0, x.ci_high - x.mean) if x.n > 1 else 0.0 for x in s]])


def _plot(ax: Axes, results: Sequence[ConfigResult], metric: str) -> None:
    for label, xs, ys, err in _series(results, metric):
        err = [[0.0 if math.isnan(e) else e for e in side] for side in err]
        ax.errorbar(xs, ys, yerr=err, marker="o", capsize=3, label=label)
    info = METRICS[metric]
    ax.set_title(f"{metric} ({info.unit})", fontsize=9)
    ax.set_xlabel("robots", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)


def plot_success(results: Sequence[ConfigResult], path: Path) -> Path:
    fig = new_figure(9, 3.6)
    axes = fig.subplots(1, 2)
    for ax, metric in zip(axes, ("team_success", "success"), strict=True):
        _plot(ax, results, metric)
        ax.set_ylim(-0.05, 1.05)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    return path


def plot_metrics(results: Sequence[ConfigResult], path: Path) -> Path:
    cols = 3
    rows = math.ceil(len(CHARTED) / cols)
    fig = new_figure(11, 3.0 * rows)
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax, metric in zip(axes.flat, CHARTED, strict=False):
        _plot(ax, results, metric)
    axes.flat[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    return path


def new_figure(width: float, height: float) -> Figure:
    """A figure of ``width`` x ``height`` inches at 100 dpi, drawn by its own Agg canvas:
    matplotlib's global backend and pyplot's figure list are left alone (importing sgjax never
    changes a notebook's plotting)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=100)
    FigureCanvasAgg(fig)
    return fig
