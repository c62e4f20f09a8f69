"""Behaviour pinned across refactors: fixed seeds give the same trajectories and metric values.

``tests/data/pinned_episodes.json`` was written by this file's ``__main__`` on the code before the
layer packages and the metric registry (commit after f491b8c); a change that moves code must
leave these numbers alone (metrics within 1e-6 absolute plus 1e-6 relative, about 16 float32
ulps: the same code on another CPU, with its own vector widths, rounds differently; final poses
within 1e-5 m). A deliberate change of
a metric's definition regenerates the file and says so in the commit:
``python tests/contracts/test_pinned_episodes.py`` (it compiles with the suite's XLA flags).
Regenerated twice since: the time-to-collision's touching tolerance (CHANGELOG.md, issue 39),
and the robot-robot contact's 10 um gap (robots resting against each other flipped between
touching and apart with the last bit, so collision counts differed between an Intel and an AMD
CPU; CHANGELOG.md);
``invalid_actions`` (issue 42) added by hand, 0 in every pinned episode (their policies' actions
are all valid); the recorded-people metrics (``log_deviation``, ``log_deviation_max``,
``people_reached``, issue 68) added by hand, NaN in every pinned episode (no recorded people).
"""

from __future__ import annotations

import os
import sys

if __name__ == "__main__":
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
    import conftest  # noqa: F401  (sets XLA_FLAGS as the suite does, before jax is imported)

import json
import math
from pathlib import Path

import jax
import numpy as np
import pytest

import sgjax
from sgjax.evaluation.evaluate import run_episodes

DATA = Path(__file__).resolve().parents[1] / "data" / "pinned_episodes.json"
# scenario, policy, make options, episodes, seed, counterfactual lanes
CASES = {
    "doorway_only_local": ("doorway", "only_local", {"num_agents": 4, "time_limit": 20.0}, 6, 0,
                           True),
    "intersection_random_continuous": (
        "intersection", "random",
        {"num_agents": 3, "action_mode": "continuous", "time_limit": 15.0}, 6, 1, False),
    "hallway_stop_when_blocked_humans": (
        "hallway", "stop_when_blocked", {"num_agents": 3, "num_humans": 4, "time_limit": 15.0},
        4, 2, False),
}


def play(case: str) -> dict:
    """Metric values (per episode) and final robot positions of one pinned case."""
    scenario, policy, options, episodes, seed, counterfactual = CASES[case]
    env, params = sgjax.make(scenario, **options)
    out = run_episodes(env, params, policy, jax.random.key(seed), episodes, record=True,
                       counterfactual=counterfactual)
    final = jax.tree.map(lambda x: np.asarray(x)[-1], out.states)  # states [T + 1, E, ...]
    return {
        "metrics": {k: [None if not math.isfinite(v) else float(v) for v in np.ravel(vals)]
                    for k, vals in sorted(out.values.items())},
        "position": np.asarray(final.robots.position).round(6).tolist(),
    }


@pytest.mark.parametrize("case", sorted(CASES))
def test_pinned_episode_values_unchanged(case):
    pinned = json.loads(DATA.read_text())[case]
    now = play(case)
    assert sorted(now["metrics"]) == sorted(pinned["metrics"]), "the set of metrics changed"
    for name, values in pinned["metrics"].items():
        got = np.array([np.nan if v is None else v for v in now["metrics"][name]], float)
        want = np.array([np.nan if v is None else v for v in values], float)
        np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6, equal_nan=True,
                                   err_msg=name)
    np.testing.assert_allclose(np.array(now["position"]), np.array(pinned["position"]),
                               rtol=0, atol=1e-5)


if __name__ == "__main__":  # under the test suite's XLA flags (tests/conftest.py), as it checks
    DATA.write_text(json.dumps({case: play(case) for case in sorted(CASES)}, indent=1) + "\n")
    print("wrote", DATA)
