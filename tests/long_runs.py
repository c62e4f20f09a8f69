"""``jit_for_long_runs``: compile a program that runs long with the backend optimised.

The suite compiles with LLVM's optimisation off (``--xla_backend_optimization_level=0``,
tests/conftest.py), because most tests compile far more than they run. A test whose
program runs far longer than it compiles pays more for unoptimised code than it saves: 100
ORCA pedestrians in the hallway for 1,000 steps ran 9.3 s at level 0 against 1.7 s at level 3,
for a compile of 3.9 s against 8.6 s (2-core AMD EPYC; both ORCA long-rollout tests 36.7 s ->
24.2 s). Such a test compiles its rollout with the backend optimised, per program (``jax.jit``'s
``compiler_options``); everything else keeps the suite's flags. Level 1 rather than 3: the two
ORCA long rollouts 19.4-21.1 s at level 1 against 23.2-24.2 s at level 3 (alternated, cache
off, 2-core AMD EPYC; level 2: 19.9 s), LLVM's level-1 pipeline compiling far less for nearly
the same code. Measure before using it: the social-force and HSFM long rollouts (100
pedestrians, 1,500 steps) were slower at level 3 (43 s -> 51 s), their compile growing more
than their run shrank, and the same at level 1 as at the suite's 0 (38.1 s against 37.6 s).
"""

from __future__ import annotations

import os
from collections.abc import Callable

import jax

OPTIMISED = {"xla_backend_optimization_level": 1}


def jit_for_long_runs(fun: Callable) -> Callable:
    """``jax.jit(fun)`` compiled with the backend optimised (a no-op under
    ``SGJAX_TEST_FULL_OPTIMIZATION=1``, which already compiles everything that way)."""
    if os.environ.get("SGJAX_TEST_FULL_OPTIMIZATION") == "1":
        return jax.jit(fun)
    return jax.jit(fun, compiler_options=OPTIMISED)
