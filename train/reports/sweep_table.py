"""A grid sweep's results as a table: one parameter's values as rows, another's as columns,
each cell the objective's mean over the trial's seeds with its 95% Student-t interval.

    python -m train.reports.sweep_table runs/sweep/table6/sweep.json \\
        --rows network.others_encoder --columns algorithm.num_minibatches [--out table.md]

Reads only the results file (``sweep.json`` of ``train.sweep``: every finished trial's
per-seed scores at its last evaluation, ``user_attrs.seed_scores``); prints markdown.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from sgjax.evaluation.report import format_summary, markdown_table
from sgjax.evaluation.statistics import summarize
from sgjax.files import write_atomic


def cells(document: Mapping[str, Any], rows: str, columns: str
          ) -> dict[tuple[Any, Any], list[float]]:
    """``{(row value, column value): per-seed scores}`` of the complete trials."""
    out: dict[tuple[Any, Any], list[float]] = {}
    for trial in document["trials"]:
        if trial["state"] != "complete":
            continue
        params = trial["params"]
        missing = [k for k in (rows, columns) if k not in params]
        if missing:
            raise ValueError(f"trial {trial['number']} has no parameter {missing[0]!r}; its "
                             f"parameters are {sorted(params)}")
        key = (params[rows], params[columns])
        if key in out:
            raise ValueError(f"two complete trials at {rows}={key[0]}, {columns}={key[1]}: "
                             "not a grid")
        out[key] = [float(v) for v in trial["user_attrs"].get("seed_scores", [trial["value"]])]
    return out


def table(document: Mapping[str, Any], rows: str, columns: str, percent: bool = True
          ) -> str:
    """The markdown table (see the module docstring)."""
    found = cells(document, rows, columns)
    row_values = sorted({r for r, _ in found}, key=str)
    column_values = sorted({c for _, c in found}, key=_order)
    body = []
    for r in row_values:
        line = [str(r)]
        for c in column_values:
            scores = found.get((r, c))
            line.append("" if scores is None else format_summary(
                summarize(np.asarray(scores), binary=False, fraction=percent), percent))
        body.append(line)
    seeds = sorted({len(v) for v in found.values()})
    metric = document["space"]["objective"]["metric"]
    head = (f"{metric}{' (%)' if percent else ''}: mean over {'/'.join(map(str, seeds))} "
            f"seed(s) ± the half width of its 95% Student-t interval; rows {rows}, columns "
            f"{columns}")
    return head + "\n\n" + "\n".join(markdown_table([rows, *map(str, column_values)],
                                                    body)) + "\n"


def _order(value: Any) -> tuple:
    return (0, float(value), "") if isinstance(value, int | float) else (1, 0.0, str(value))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m train.reports.sweep_table",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("sweep", help="sweep.json of train.sweep")
    parser.add_argument("--rows", required=True, help="parameter whose values are the rows")
    parser.add_argument("--columns", required=True, help="parameter whose values are the columns")
    parser.add_argument("--fraction", action="store_true", help="values as they are, not in %%")
    parser.add_argument("--out", default=None, help="also write the table to this file")
    args = parser.parse_args(argv)
    try:
        document = json.loads(Path(args.sweep).read_text())
        text = table(document, args.rows, args.columns, percent=not args.fraction)
    except (OSError, ValueError, KeyError) as err:
        raise SystemExit(f"sweep_table: {args.sweep}: {err}") from err
    print(text)
    if args.out:
        write_atomic(Path(args.out), text)


if __name__ == "__main__":
    main()
