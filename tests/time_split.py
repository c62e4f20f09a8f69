"""Sum a ``SGJAX_TEST_TIME_SPLIT`` file (see tests/conftest.py) by test file and by phase.

    SGJAX_TEST_TIME_SPLIT=/tmp/split.jsonl python -m pytest -n 2 --dist loadfile
    python tests/time_split.py /tmp/split.jsonl [--tests 30]
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict

PHASES = ("trace", "lower", "compile")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file")
    parser.add_argument("--tests", type=int, default=30, help="slowest tests to list")
    args = parser.parse_args()
    with open(args.file) as rows:
        tests = [json.loads(line) for line in rows if line.strip()]
    by_file: dict[str, dict[str, float]] = defaultdict(lambda: defaultdict(float))
    for row in tests:
        total = by_file[row["test"].split("::")[0]]
        for key in ("wall", *PHASES):
            total[key] += row.get(key, 0.0)
        total["tests"] += 1
    header = f"{'wall s':>8} {'trace':>7} {'lower':>7} {'compile':>8} {'rest':>7}"
    print(f"{header}  tests  file")
    for name, t in sorted(by_file.items(), key=lambda item: -item[1]["wall"]):
        rest = t["wall"] - sum(t[p] for p in PHASES)
        print(f"{t['wall']:8.1f} {t['trace']:7.1f} {t['lower']:7.1f} {t['compile']:8.1f} "
              f"{rest:7.1f}  {int(t['tests']):5d}  {name}")
    grand = {key: sum(t[key] for t in by_file.values()) for key in ("wall", *PHASES)}
    print(f"{grand['wall']:8.1f} {grand['trace']:7.1f} {grand['lower']:7.1f} "
          f"{grand['compile']:8.1f} {grand['wall'] - sum(grand[p] for p in PHASES):7.1f}  "
          f"{len(tests):5d}  all")
    print(f"\nslowest {args.tests} tests")
    for row in sorted(tests, key=lambda r: -r["wall"])[:args.tests]:
        rest = row["wall"] - sum(row.get(p, 0.0) for p in PHASES)
        print(f"{row['wall']:8.1f} {row.get('trace', 0):7.1f} {row.get('lower', 0):7.1f} "
              f"{row.get('compile', 0):8.1f} {rest:7.1f}  {row['test']}")


if __name__ == "__main__":
    main()
