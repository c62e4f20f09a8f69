"""Keep the tables in a Markdown document equal to the files the runs wrote.

A block in the document between

    <!-- generated from docs/results/table5/ablation.md -->
    ...
    <!-- end generated -->

holds that file's text (path relative to the repository root), less its title lines (lines
beginning ``# ``: the document's own heading names the section), its own section headings
moved one level below the document's section that holds the block (a file's ``## Summary``
under the document's ``## Transfer`` becomes ``### Summary``), so the page's outline stays
the page's. The runs write those files
(``train.reproduce``, ``--from-results``, ``train.ablation``, ``python -m train``), so a number
in the document is never copied by hand::

    python -m train.reports.results_doc docs/results.md           # exit 1 naming stale blocks
    python -m train.reports.results_doc docs/results.md --write   # rewrite them from the files

A plain include, written here rather than taken from ``cogapp`` (which runs Python code kept in
the document): the document carries no code, only the names of the files.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BLOCK = re.compile(r"(<!-- generated from (?P<source>\S+) -->\n)(?P<body>.*?)"
                   r"(<!-- end generated -->)", re.DOTALL)


class DocumentError(ValueError):
    """A document whose generated blocks cannot be checked (missing file, unclosed block)."""


HEADING = re.compile(r"^(#{1,6}) ")


def heading_level(text: str) -> int:
    """The level of the last Markdown heading in ``text`` (0 when none), fenced code left out."""
    level, fenced = 0, False
    for line in text.splitlines():
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and (match := HEADING.match(line)):
            level = len(match[1])
    return level


def generated_text(source: Path, level: int = 1) -> str:
    """The block text for ``source``: its lines less the ``# `` title lines, ending in a
    newline, without leading or trailing blank lines; its ``##`` headings (and deeper) moved to
    ``level + 1`` (and deeper) for a block inside a section of ``level`` (at most ``######``)."""
    lines, fenced = [], False
    for line in source.read_text().splitlines():
        if line.startswith("```"):
            fenced = not fenced
        match = None if fenced else HEADING.match(line)
        if match and len(match[1]) == 1:
            continue
        if match:
            depth = min(len(match[1]) - 1 + max(level, 1), 6)
            line = "#" * depth + line[len(match[1]):]
        lines.append(line)
    return "\n".join(lines).strip("\n") + "\n"


def refresh(text: str, where: str, root: Path = ROOT) -> tuple[str, list[str]]:
    """``text`` with every generated block rewritten from its file, and the sources of the
    blocks that differed. Raises :class:`DocumentError` naming ``where`` and the block."""
    opened = text.count("<!-- generated from ")
    closed = len(BLOCK.findall(text))
    if opened != closed:
        raise DocumentError(f"{where}: {opened} '<!-- generated from' markers but {closed} "
                            "closed by '<!-- end generated -->'")
    stale: list[str] = []

    def replace(match: re.Match) -> str:
        source = root / match["source"]
        if not source.is_file():
            line = text.count("\n", 0, match.start()) + 1
            raise DocumentError(f"{where}:{line}: generated block names {match['source']}, "
                                "which does not exist")
        body = generated_text(source, heading_level(text[:match.start()]))
        if body != match["body"]:
            stale.append(match["source"])
        return f"{match.group(1)}{body}{match.group(4)}"

    return BLOCK.sub(replace, text), stale


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m train.reports.results_doc",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("documents", nargs="+", help="Markdown files (docs/results.md)")
    parser.add_argument("--write", action="store_true",
                        help="rewrite the stale blocks instead of failing on them")
    args = parser.parse_args(argv)
    failed = False
    for name in args.documents:
        path = Path(name)
        new, stale = refresh(path.read_text(), name, ROOT)
        if args.write and stale:
            path.write_text(new)
            print(f"{name}: rewrote {len(stale)} block(s): {', '.join(stale)}")
        elif stale:
            failed = True
            print(f"{name}: {len(stale)} block(s) differ from their files: {', '.join(stale)} "
                  f"(python -m train.reports.results_doc {name} --write)")
        else:
            print(f"{name}: every generated block matches its file")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
