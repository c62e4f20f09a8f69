"""Sum a ``SGJAX_TEST_TIME_SPLIT`` file (see tests/conftest.py) by test file and by phase.

    SGJAX_TEST_TIME_SPLIT=/tmp/split.jsonl python -m pytest -n 2 --dist loadfile
    python tests/time_split.py /tmp/split.jsonl [--tests 30] [--programs 20]

``cpu s``: the workers' CPU seconds (every thread), ``child``: their subprocesses' (rows written
before these were kept show 0); ``compiles``: XLA compiles of any size (mostly the single
primitives of eager-mode tests). ``workers``: each xdist worker's tests, the seconds they ran
and when its first started and its last ended, from the earliest start: how evenly
``--dist loadfile`` shared the files out.

``--programs``: the compiles of 0.3 s or more summed by program name (``jit(episodes)``, the
evaluation; ``jit(<lambda>)``, mostly training updates), with how many there were and the files
that compiled them most: where sharing one compiled program between tests would pay.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict

PHASES = ("trace", "lower", "compile")
SUMMED = ("wall", *PHASES, "cpu", "cpu_children", "compiles")  # summed by file and in all


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file")
    parser.add_argument("--tests", type=int, default=30, help="slowest tests to list")
    parser.add_argument("--programs", type=int, default=0,
                        help="programs to list by compile seconds (0: none)")
    args = parser.parse_args()
    with open(args.file) as rows:
        tests = [json.loads(line) for line in rows if line.strip()]
    by_file: dict[str, dict[str, float]] = defaultdict(lambda: defaultdict(float))
    for row in tests:
        total = by_file[row["test"].split("::")[0]]
        for key in SUMMED:
            total[key] += row.get(key, 0.0)
        total["tests"] += 1
    header = (f"{'wall s':>8} {'trace':>7} {'lower':>7} {'compile':>8} {'rest':>7} {'cpu s':>7} "
              f"{'child':>6} {'compiles':>8}")
    print(f"{header}  tests  file")
    for name, t in sorted(by_file.items(), key=lambda item: -item[1]["wall"]):
        print(summed_row(t, int(t["tests"]), name))
    grand = {key: sum(t[key] for t in by_file.values()) for key in SUMMED}
    print(summed_row(grand, len(tests), "all"))
    print_workers(tests)
    print(f"\nslowest {args.tests} tests")
    for row in sorted(tests, key=lambda r: -r["wall"])[:args.tests]:
        rest = row["wall"] - sum(row.get(p, 0.0) for p in PHASES)
        print(f"{row['wall']:8.1f} {row.get('trace', 0):7.1f} {row.get('lower', 0):7.1f} "
              f"{row.get('compile', 0):8.1f} {rest:7.1f}  {row['test']}")
    if args.programs:
        print_programs(tests, args.programs)


def summed_row(t: dict[str, float], tests: int, name: str) -> str:
    """One line of the table: ``t``'s summed columns, its test count and its name."""
    rest = t["wall"] - sum(t[p] for p in PHASES)
    return (f"{t['wall']:8.1f} {t['trace']:7.1f} {t['lower']:7.1f} {t['compile']:8.1f} "
            f"{rest:7.1f} {t['cpu']:7.1f} {t['cpu_children']:6.1f} {int(t['compiles']):8d}  "
            f"{tests:5d}  {name}")


def print_workers(tests: list[dict]) -> None:
    """Each worker's tests, busy seconds, first start and last end (rows that record them)."""
    timed = [row for row in tests if "start" in row and "worker" in row]
    if not timed:
        return
    origin = min(row["start"] for row in timed)
    print("\nworkers: tests, seconds in tests, first start and last end (s from the first start)")
    for worker in sorted({row["worker"] for row in timed}):
        mine = [row for row in timed if row["worker"] == worker]
        first = min(row["start"] for row in mine) - origin
        last = max(row["start"] + row["wall"] for row in mine) - origin
        print(f"  {worker}: {len(mine)} tests, {sum(r['wall'] for r in mine):.0f} s, "
              f"{first:.0f} -> {last:.0f}")


def print_programs(tests: list[dict], count: int) -> None:
    """The ``count`` programs that took the most compile seconds, summed over the suite."""
    seconds: dict[str, float] = defaultdict(float)
    compiles: dict[str, int] = defaultdict(int)
    files: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    for row in tests:
        for name, spent in row.get("programs", []):
            seconds[name] += spent
            compiles[name] += 1
            files[name][row["test"].split("::")[0].rsplit("/", 1)[-1]] += 1
    print(f"\ncompiles of 0.3 s or more by program ({sum(seconds.values()):.1f} s in all)")
    for name in sorted(seconds, key=lambda n: -seconds[n])[:count]:
        most = sorted(files[name].items(), key=lambda item: -item[1])[:3]
        where = ", ".join(f"{file} {n}" for file, n in most)
        print(f"{seconds[name]:8.1f} {compiles[name]:5d}  {name}  ({where})")


if __name__ == "__main__":
    main()
