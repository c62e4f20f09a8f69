"""``python -m train.tables PATH... [--check]``: every result file's markdown tables written
again from its JSON by the current report code, so that no published table is older than the
code that formats it, and none is edited by hand.

A ``PATH`` is a result file or a folder searched for them (``docs/results``). Each JSON file is
read by its ``schema_version`` and its tables are written beside it:

- ``sgjax.reproduce/1`` (``results.json``): Tables 3-4 and the comparisons
  (:func:`train.reproduce.tables_of`; the tables at 4 robots, the command's default);
- ``sgjax.ablation/1`` (``ablation.json``): ``ablation.md`` (:func:`train.ablation.table_of`);
- ``sgjax.seed_spread/1`` and ``sgjax.paired/1`` (a training run's ``eval/``):
  ``seed_spread.md`` and ``paired.md`` (:mod:`train.cli`);
- ``sgjax.transfer/1``: ``transfer.md`` (:func:`train.transfer.tables`);
- ``sgjax.crowd_fit/1``: ``crowd_fit.md`` (:func:`sgjax.evaluation.crowd_fit.table`).

Other files (``sgjax.evaluate/1`` and ``sgjax.sweep/1``, whose tables need the run's own
objects; provenance blocks; files without a schema) are skipped and counted. ``--check`` writes
nothing and exits 1 naming every table that differs from what its JSON gives (the test suite
runs it over ``docs/results``); ``train.reports.results_doc`` then checks that the documents'
blocks equal the tables.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from sgjax.evaluation import crowd_fit
from train import ablation, reproduce, transfer
from train.cli import paired_markdown, seed_spread_markdown
from train.reports.result_schemas import ABLATION, PAIRED, REPRODUCE, SEED_SPREAD, TRANSFER

Tables = Callable[[dict[str, Any]], dict[str, str]]

WRITERS: dict[str, Tables] = {
    REPRODUCE: reproduce.tables_of,
    ABLATION: lambda d: {"ablation.md": ablation.table_of(d)},
    SEED_SPREAD: lambda d: {"seed_spread.md": seed_spread_markdown(d)},
    PAIRED: lambda d: {"paired.md": paired_markdown(d)},
    TRANSFER: lambda d: {"transfer.md": transfer.tables(d)},
    crowd_fit.SCHEMA: lambda d: {"crowd_fit.md": crowd_fit.table(d) + "\n"},
}


def result_files(paths: Iterable[Path]) -> list[Path]:
    """Every JSON file named or under a named folder, sorted. Raises ``ValueError`` naming a
    path that does not exist."""
    found: list[Path] = []
    for path in paths:
        if path.is_dir():
            found += sorted(path.rglob("*.json"))
        elif path.is_file():
            found.append(path)
        else:
            raise ValueError(f"{path}: no such file or folder")
    return found


def tables_for(path: Path) -> dict[Path, str] | None:
    """The tables ``path``'s JSON gives, by the file each belongs in (beside it), or None
    for a file no writer reads. Raises ``ValueError`` naming the file when its JSON does not
    parse or its tables cannot be made from it."""
    try:
        document = json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise ValueError(f"{path}: not JSON ({err})") from err
    version = document.get("schema_version") if isinstance(document, dict) else None
    writer = WRITERS.get(version)
    if writer is None:
        return None
    try:
        tables = writer(document)
    except (KeyError, TypeError, ValueError) as err:
        raise ValueError(f"{path}: a {version} file whose tables cannot be made "
                         f"({type(err).__name__}: {err})") from err
    return {path.parent / name: text for name, text in tables.items()}


def regenerate(paths: Iterable[Path], check: bool) -> tuple[list[Path], list[Path], int]:
    """Write (or, with ``check``, only compare) every table of every result file under
    ``paths``: ``(tables written or differing, tables already equal, files skipped)``."""
    changed, same, skipped = [], [], 0
    for path in result_files(paths):
        tables = tables_for(path)
        if tables is None:
            skipped += 1
            continue
        for target, text in tables.items():
            if target.is_file() and target.read_text() == text:
                same.append(target)
                continue
            changed.append(target)
            if not check:
                target.write_text(text)
    return changed, same, skipped


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m train.tables",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("paths", nargs="+", type=Path,
                        help="result files or folders to search (docs/results)")
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 naming the tables that differ")
    args = parser.parse_args(argv)
    try:
        changed, same, skipped = regenerate(args.paths, args.check)
    except ValueError as err:
        raise SystemExit(f"tables: {err}") from err
    verb = "differ from their JSON" if args.check else "written again"
    for target in changed:
        print(f"{target}: {verb}")
    print(f"{len(same)} table(s) equal to their JSON, {len(changed)} {verb}; {skipped} JSON "
          "file(s) without tables here skipped")
    return 1 if args.check and changed else 0


if __name__ == "__main__":
    sys.exit(main())
