"""Every registered metric meets the metric contract.

Parametrised over the metric registry, so a metric is tested the day it is registered: one
batch of episodes (one compile) on a map with a conflict zone, pedestrians and an absent robot
slot, with the counterfactual lanes on, checks for each metric:

* its catalogue entry is complete: definition, source and unit, a level and a reduction;
* per-episode values ``[E]``, per-robot values ``[E, R]`` for robot-level metrics only;
* values are finite or NaN (never inf); binary metrics are 0, 1 or NaN; fractions in [0, 1];
* no value for a robot slot that is not in the episode (NaN there).
"""

from __future__ import annotations

import functools

import jax
import numpy as np
import pytest

import sgjax
from sgjax.evaluation.evaluate import run_episodes
from sgjax.evaluation.metrics import METRICS
from sgjax.evaluation.metrics.base import LEVELS, REDUCTIONS

PRESENT, SLOTS, EPISODES = 2, 3, 3


@functools.cache
def batch():
    """Doorway, 2 of 3 robot slots, 3 pedestrians, 8 s, counterfactual lanes: ``(episodes,
    present [E, R])``."""
    env, params = sgjax.make("doorway", num_agents=PRESENT, max_agents=SLOTS, num_humans=3,
                             time_limit=8.0)
    out = run_episodes(env, params, "random", jax.random.key(0), EPISODES, record=True,
                       counterfactual=True)
    return out, np.asarray(out.states.robots.present[0])


@pytest.mark.parametrize("name", METRICS.names())
def test_metric(name):
    info = METRICS[name]
    assert info.definition.strip() and info.source.strip() and info.unit.strip()
    assert info.level in LEVELS and info.reduce in REDUCTIONS
    assert not info.binary or info.level == "episode"
    out, present = batch()
    values = np.asarray(out.values[name])
    assert values.shape == (EPISODES,) and values.dtype == np.float32
    assert not np.isinf(values).any()
    if info.binary:
        assert np.isin(values[~np.isnan(values)], (0.0, 1.0)).all()
    if info.unit == "fraction":
        assert ((values[~np.isnan(values)] >= 0) & (values[~np.isnan(values)] <= 1)).all()
    if info.level == "episode":
        assert name not in out.robot
        return
    robot = np.asarray(out.robot[name])
    assert robot.shape == (EPISODES, SLOTS) and robot.dtype == np.float32
    assert not np.isinf(robot).any()
    assert present.sum(axis=1).tolist() == [PRESENT] * EPISODES
    assert np.isnan(robot[~present]).all(), "a value for a robot not in the episode"


def test_every_metric_has_a_value_and_nothing_else():
    out, _ = batch()
    assert sorted(out.values) == sorted(METRICS.names())  # (jit returns dicts sorted)
    assert set(out.robot) == {i.name for i in METRICS if i.level == "robot"}
