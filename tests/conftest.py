"""Shared test settings: headless matplotlib, and one JAX compilation cache per test session.

Tests compile many identical programs (the same environment's step in several tests, and every
primitive that eager-mode tests dispatch); a persistent compilation cache shared by the xdist
workers of one session compiles each of them once. Programs that compile in under 0.1 s (the
single primitives that eager-mode tests dispatch, hundreds per test) are not written to it:
writing and looking them up cost more than compiling them again (three eager-heavy test files
140 s -> 131 s alone). The cache lives in a fresh temporary folder per session (a run from a
fresh clone pays every compile once), unless
``SGJAX_TEST_COMPILATION_CACHE`` names a folder to keep between runs. ``SGJAX_TEST_NO_CACHE=1``
turns it off. What the cache is worth (measured on the 2-core AMD EPYC, 2026-11-27, every write
and read of a suite run logged): 529 programs written, for 34 s of CPU (serialising the
executable, compressing it, writing it); 85 of them read back in the suite's own processes (141
reads, 40 of them in another file than the writer's), saving about 79 s of compiling, besides
what the commands' subprocesses read. A threshold of 0.3, 0.5 or 1 s instead of 0.1 s saves
fewer writes than it loses reads (net 37, 30, 22 s instead of 45 s). The dev extra installs
``zstandard``, which JAX uses instead of zlib to compress the entries: the suite's 925 MB of
executables compress in 1.6 s instead of 13.7 s.

Tests compile far more than they run, and most of an XLA:CPU compile is LLVM optimising the
generated code: the tests compile with ``--xla_backend_optimization_level=0`` (about a third off)
and ``--xla_cpu_use_fusion_emitters=false`` (XLA:CPU's older elemental emitters: the same
arithmetic, half the compile time again; doorway step 2.2 s -> 0.9 s, a tiny trainer update
5 s -> 2.5 s on the 2-core machine) and ``--xla_cpu_parallel_codegen_split_count=1`` (one LLVM
module per program: the split only pays where idle cores wait, and the suite's two workers
leave none; tests/trainer/test_train.py + tests/terms/test_presets.py 225 s -> 210 s),
appended to ``XLA_FLAGS`` so that subprocesses inherit them.
A caution found with them (2026-11-29): with ``--xla_backend_optimization_level=0`` and
``--xla_cpu_use_fusion_emitters=false`` together, ``jax.grad`` of the every-body Moussaid forces
on a moving crowd (the 160-pedestrian crossing after one step) differs by up to 2.07 from the
same program compiled without them (either flag alone gives the right gradient; the cell-list
gradient is right under both): tests/kernels/test_neighbor_grid.py checks its gradients at the
reset state for that reason. A gradient test that fails only under the suite's flags may be
this miscompile: run it with ``SGJAX_TEST_FULL_OPTIMIZATION=1``.
``SGJAX_TEST_FULL_OPTIMIZATION=1`` compiles as users do (one test's margin depends on it:
tests/kernels/test_orca_humans.py's corridor counter-flow overlaps by 12 mm, tolerance 10 mm,
when fully optimised; see the note there).

Tracing allocates millions of short-lived Python objects, and the cyclic garbage collector
walks every live one (JAX's caches included) each time its counters trip: the objects alive
after collection are frozen out of its sight and its first threshold raised from 700 to 200,000
allocations (a test file 6% faster; turning it off entirely saved 11% but grew a worker past
1.7 GB in a dozen tests).
"""

from __future__ import annotations

import gc
import os
import shutil
import tempfile

import matplotlib

matplotlib.use("Agg")

from sgjax.compilation_cache import FAST_CPU_COMPILE, knows_fast_cpu_compile  # noqa: E402

# The commands' elemental-emitter flag only where this jaxlib knows it (XLA aborts otherwise).
FAST_COMPILE = ("--xla_backend_optimization_level=0",
                *((FAST_CPU_COMPILE,) if knows_fast_cpu_compile() else ()),
                "--xla_cpu_parallel_codegen_split_count=1")
if os.environ.get("SGJAX_TEST_FULL_OPTIMIZATION") != "1":
    _flags = os.environ.get("XLA_FLAGS", "")
    _missing = [flag for flag in FAST_COMPILE if flag.split("=")[0] not in _flags]
    os.environ["XLA_FLAGS"] = " ".join([_flags, *_missing]).strip()

_CACHE_ENV = "SGJAX_TEST_COMPILATION_CACHE"
_OWNED_ENV = "SGJAX_TEST_COMPILATION_CACHE_OWNED"


def pytest_configure(config):
    gc.collect()
    gc.freeze()
    gc.set_threshold(200_000, 50, 1000)
    if os.environ.get("SGJAX_TEST_NO_CACHE") == "1":
        return
    if _CACHE_ENV not in os.environ:  # the controller (or a plain run) makes the folder
        os.environ[_CACHE_ENV] = tempfile.mkdtemp(prefix="sgjax-test-jax-cache-")
        os.environ[_OWNED_ENV] = str(os.getpid())
    # Read by JAX at import (workers and subprocesses inherit them), and set here too in case
    # JAX is already imported.
    settings = {"jax_compilation_cache_dir": os.environ[_CACHE_ENV],
                "jax_persistent_cache_min_compile_time_secs": 0.1,
                "jax_persistent_cache_min_entry_size_bytes": 0}
    for name, value in settings.items():
        os.environ[name.upper()] = str(value)
    import jax

    for name, value in settings.items():
        jax.config.update(name, value)


def pytest_unconfigure(config):
    if os.environ.get(_OWNED_ENV) == str(os.getpid()):
        shutil.rmtree(os.environ.get(_CACHE_ENV, ""), ignore_errors=True)


def pytest_collection_modifyitems(session, config, items):
    """Files with the most slow tests first (stable otherwise): with ``--dist loadfile`` the
    workers take the long files early and the short ones fill in at the end."""
    slow = {}
    for item in items:
        slow[item.path] = slow.get(item.path, 0) + (item.get_closest_marker("slow") is not None)
    items.sort(key=lambda item: -slow[item.path])


# --- Where each test's time goes (opt-in) ---------------------------------------------------
# SGJAX_TEST_TIME_SPLIT=FILE appends one line per test to FILE (every xdist worker appends):
# nodeid, the xdist worker, the start (Unix seconds), wall seconds, and the seconds JAX
# reported spending in tracing, lowering to MLIR and XLA compiling inside it (jax.monitoring
# duration events; compiling includes loading from the compilation cache) and the cache's
# hits and misses; the rest is running and Python. ``cpu``:
# the worker's CPU seconds in the test (all its threads); ``cpu_children``: those of the
# subprocesses it started and waited for (commands, a browser once its driver quits).
# ``python tests/time_split.py FILE`` sums it by file and by phase.
_SPLIT_ENV = "SGJAX_TEST_TIME_SPLIT"
_PHASES = {"/jax/core/compile/jaxpr_trace_duration": "trace",
           "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower",
           "/jax/core/compile/backend_compile_duration": "compile"}
_spent: dict[str, float] = {}


_COUNTS = {"/jax/compilation_cache/cache_hits": "cache_hits",
           "/jax/compilation_cache/cache_misses": "cache_misses"}


def _listen(event: str, seconds: float, fun_name: str = "", **_kwargs) -> None:
    phase = _PHASES.get(event)
    if phase is not None:
        _spent[phase] = _spent.get(phase, 0.0) + seconds
        if phase == "compile":
            _spent["compiles"] = _spent.get("compiles", 0) + 1
            if seconds >= 0.3:  # the programs that cost (name, seconds)
                _spent.setdefault("programs", []).append([fun_name, round(seconds, 2)])


def _count(event: str, **_kwargs) -> None:
    name = _COUNTS.get(event)
    if name is not None:
        _spent[name] = _spent.get(name, 0) + 1


if os.environ.get(_SPLIT_ENV):
    import json
    import time

    import jax.monitoring
    import pytest

    jax.monitoring.register_event_duration_secs_listener(_listen)
    jax.monitoring.register_event_listener(_count)

    def _cpu_seconds() -> tuple[float, float]:
        """(this process's, its finished children's) user + system CPU seconds."""
        import resource

        own, children = (resource.getrusage(who) for who in (resource.RUSAGE_SELF,
                                                              resource.RUSAGE_CHILDREN))
        return own.ru_utime + own.ru_stime, children.ru_utime + children.ru_stime

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_protocol(item, nextitem):
        _spent.clear()
        started, start, (own, children) = time.time(), time.perf_counter(), _cpu_seconds()
        yield
        own_after, children_after = _cpu_seconds()
        row = {"test": item.nodeid, "worker": os.environ.get("PYTEST_XDIST_WORKER", "main"),
               "start": started,
               "wall": time.perf_counter() - start,
               "cpu": own_after - own, "cpu_children": children_after - children, **_spent}
        with open(os.environ[_SPLIT_ENV], "a") as out:
            out.write(json.dumps(row) + "\n")
