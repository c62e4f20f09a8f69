"""The tables of docs/metrics.md, generated from the metric registry and
:class:`~sgjax.evaluation.metrics.base.MetricConstants`.

::

    python -m sgjax.evaluation.metrics.catalogue            # rewrite docs/metrics.md's tables
    python -m sgjax.evaluation.metrics.catalogue --check    # exit 1 if they are out of date

Each table sits between ``<!-- begin NAME ... -->`` and ``<!-- end NAME -->`` markers; the rest
of the page is left as it is. ``tests/evaluation/test_metrics.py`` checks that the page agrees
with the registry.
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path

from sgjax.evaluation import counterfactual  # noqa: F401  (registers the counterfactual metrics)
from sgjax.evaluation.metrics.base import MetricInfo
from sgjax.evaluation.metrics.constants import DEFAULT_CONSTANTS, MetricConstants
from sgjax.evaluation.metrics.registration import METRICS

COMMAND = "python -m sgjax.evaluation.metrics.catalogue"
DOCS = Path("docs") / "metrics.md"


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|")


def _table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def level_text(info: MetricInfo) -> str:
    """How a metric is measured and reduced, as the definitions table says it."""
    if info.level == "robot":
        return f"robot ({info.reduce} over robots)"
    return "episode, yes/no" if info.binary else "episode"


def definitions_table(infos: Iterable[MetricInfo] = METRICS) -> str:
    """Every registered metric: name, unit, level (reduction), definition, source."""
    return _table(["Metric", "Unit", "Level (reduction)", "Definition", "Source"],
                  ([f"`{i.name}`", i.unit, level_text(i), i.definition, i.source]
                   for i in infos))


def constants_table(constants: MetricConstants = DEFAULT_CONSTANTS) -> str:
    """Every constant: name, value with its unit, and what uses it (the field metadata)."""
    rows = []
    for field in dataclasses.fields(constants):
        value = getattr(constants, field.name)
        shown = ", ".join(str(v) for v in value) if isinstance(value, tuple) else str(value)
        rows.append([f"`{field.name}`", f"{shown} {field.metadata.get('unit', '')}".strip(),
                     field.metadata.get("used_by", "")])
    return _table(["Constant", "Value", "Used by"], rows)


def sections() -> dict[str, str]:
    """The generated tables by marker name."""
    return {"constants": constants_table(), "definitions": definitions_table()}


def render(text: str) -> str:
    """``text`` (docs/metrics.md) with every generated table replaced by the current one."""
    for name, table in sections().items():
        begin, end = rf"<!-- begin {name}\b[^\n]*-->\n", rf"<!-- end {name} -->"
        pattern = re.compile(rf"({begin})(?:.*?\n)?({end})", re.DOTALL)
        if not pattern.search(text):
            raise ValueError(f"no '<!-- begin {name} ... -->' ... '<!-- end {name} -->' "
                             "markers in the page")
        text = pattern.sub(lambda m, t=table: m.group(1) + t + "\n" + m.group(2), text)
    return text


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog=COMMAND, description=__doc__.split("\n\n")[0])
    parser.add_argument("path", nargs="?", type=Path, default=DOCS,
                        help=f"the page to update (default {DOCS})")
    parser.add_argument("--check", action="store_true",
                        help="only check: exit 1 if the page's tables are out of date")
    args = parser.parse_args(argv)
    text = args.path.read_text()
    new = render(text)
    if args.check:
        if new != text:
            print(f"{args.path}: the metric tables are out of date; run {COMMAND}",
                  file=sys.stderr)
            return 1
        print(f"{args.path}: the metric tables agree with the registry")
        return 0
    if new != text:
        args.path.write_text(new)
        print(f"wrote {args.path}")
    else:
        print(f"{args.path}: already up to date")
    return 0


if __name__ == "__main__":
    sys.exit(main())
