"""The map checks' time and peak memory on large and dense maps (``sgjax maps check``).

Each row runs ``sgjax maps check`` on one map in a fresh process and prints its wall time and
peak resident memory (the process's ``ru_maxrss``, the interpreter and imports included: about
200 MB of it). The maps: SocialGym 2.0's largest floor (GDC3, imported; needs
``../shared/sg2maps``), ``N`` walls 10 cm long packed into a 20 m room (the editor's security
report: 200,000 of them took the editor's server past 24 GB), and the same walls spread over a
600 m floor. A map past ``sgjax.maps.size_limits`` is refused at once (the last row).

    python bench/map_check.py
    python bench/map_check.py --packed 50000 200000
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))
from dense_maps import packed_room  # noqa: E402

MEASURE = """
import resource, sys
from sgjax.maps.check import check_file
problems = check_file(sys.argv[1])
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(len(problems), round(peak))
"""


def measure(path: Path) -> tuple[float, int, int]:
    """``(seconds, problems, peak MB)`` of checking ``path`` in a new process."""
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", MEASURE, str(path)], check=True,
                         capture_output=True, text=True).stdout.split()
    return time.perf_counter() - start, int(out[0]), int(out[1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--packed", type=int, nargs="+", default=[20_000, 50_000, 200_000])
    args = parser.parse_args()
    from sgjax.maps.size_limits import MAX_WALLS

    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text()
                .splitlines() if line.startswith("model name")), platform.processor())
    print(f"# sgjax maps check, {cpu}, Python {platform.python_version()}")
    print("| map | walls | seconds | peak MB | problems |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        cases = []
        gdc3 = REPO.parent / "shared" / "sg2maps" / "GDC3"
        if gdc3.is_dir():
            from sgjax.maps import import_socialgym

            cases.append(("GDC3 (SocialGym 2.0)", import_socialgym(gdc3).to_json()))
        cases += [("packed 20 m room", packed_room(n)) for n in args.packed]
        cases.append(("spread over a 600 m floor", packed_room(max(args.packed), size=600.0)))
        cases.append(("past the wall limit", packed_room(MAX_WALLS + 1)))
        for k, (name, data) in enumerate(cases):
            path = Path(folder) / f"map{k}.json"
            path.write_text(json.dumps(data))
            seconds, problems, peak = measure(path)
            print(f"| {name} | {len(data['walls']):,} | {seconds:.1f} | {peak} | {problems} |",
                  flush=True)


if __name__ == "__main__":
    main()
