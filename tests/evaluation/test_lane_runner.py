"""The one-program evaluation (``LaneRunner``, ``evaluate_lanes``): every policy at every robot
count as lanes of one loop plays the episodes of the separate runs, and ``record_lanes`` keeps
the states of chosen episodes only; ``ParamLaneRunner``'s lanes (one policy, a parameter set
each) play the episodes of separate runs too."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sgjax.environment.options import MakeOptions
from sgjax.evaluation.evaluate import evaluate, evaluate_lanes, params_by_count, run_episodes
from sgjax.evaluation.policies import RecurrentPolicy, load_policy, only_local
from sgjax.evaluation.runner import EpisodeRunner, LaneRunner, ParamLaneRunner

SCENARIO = "doorway"
# random reads the per-step keys, stop_when_blocked the state: both must match lane by lane
POLICIES = ["random", "only_local", "stop_when_blocked"]
COUNTS = [2, 3]
EPISODES = 3
SEED = 5
OPTIONS = MakeOptions.from_keywords("test", time_limit=12.0)


def leaves_equal(a, b) -> None:
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


@pytest.mark.slow
def test_lanes_play_the_episodes_of_separate_runs():
    """Per-episode values of every (policy, count) lane equal ``run_episodes`` of that policy at
    that count with the same key, whether the counts are calls of the program or lanes too;
    the summaries equal ``evaluate``'s; the recorded lane is that episode, state for state, as
    a separate recording run plays it. (The separate runs are played once for both layouts;
    the recorded policy's at every count by its one recording program, which
    ``test_record_lanes_keeps_only_those_episodes`` plays too.)"""
    record = (2, COUNTS[0], 1)  # stop_when_blocked at 2 robots, episode 1
    env, by_count = params_by_count(SCENARIO, COUNTS, options=OPTIONS)
    alone = {(policy, n): run_episodes(env, by_count[n], policy, jax.random.key(SEED), EPISODES,
                                       record=p == record[0])
             for p, policy in enumerate(POLICIES) for n in COUNTS}
    separate = evaluate([SCENARIO], POLICIES, COUNTS, EPISODES, seed=SEED, options=OPTIONS,
                        log=None)
    for at_once in (False, True):
        results, values, states = evaluate_lanes(SCENARIO, POLICIES, COUNTS, EPISODES,
                                                 seed=SEED, options=OPTIONS, record=record,
                                                 counts_at_once=at_once)
        assert values["success"].shape == (len(POLICIES), len(COUNTS), EPISODES)
        for p, policy in enumerate(POLICIES):
            for k, n in enumerate(COUNTS):
                run = alone[policy, n]
                for name, per_episode in run.values.items():
                    # The same episodes (states equal below, to the bit); a metric that sums
                    # floats over steps may round differently in the two programs (XLA fuses
                    # them differently: jerk_mean once differed by 1 ulp), so those agree to
                    # float32 rounding.
                    np.testing.assert_allclose(
                        values[name][p, k], per_episode, rtol=1e-6, atol=0,
                        err_msg=f"counts at once {at_once}, {policy} at {n} robots: {name}")
                if (p, n) == record[:2]:
                    leaves_equal(states, jax.tree.map(lambda leaf: leaf[:, record[2]],
                                                      run.states))
        assert [(r.policy, r.num_agents) for r in results] == [
            (r.policy, r.num_agents) for r in separate]
        for mine, theirs in zip(results, separate, strict=True):
            ours, others = mine.as_dict()["metrics"], theirs.as_dict()["metrics"]
            assert ours.keys() == others.keys()
            for name in ours:
                for field, value in ours[name].items():
                    if isinstance(value, float):
                        assert value == pytest.approx(others[name][field], rel=1e-6, abs=1e-9,
                                                      nan_ok=True), (at_once, name, field)
                    else:
                        assert value == others[name][field], (at_once, name, field)
            assert mine.steps_played >= theirs.steps_played
        assert results[0].compile_seconds > 0
        assert all(r.compile_seconds == 0.0 for r in results[1:])  # one program for them all


def test_record_lanes_keeps_only_those_episodes():
    """``record_lanes`` records the chosen episodes as ``record=True`` does (and stops early);
    the other results are unchanged. (The ``record=True`` run is the one the test above plays:
    ``run_episodes`` keeps a baseline's compiled run for the process.)"""
    env, by_count = params_by_count(SCENARIO, COUNTS, options=OPTIONS)
    params, key = by_count[2], jax.random.key(1)
    every = run_episodes(env, params, "stop_when_blocked", key, EPISODES, record=True)
    some = EpisodeRunner(env, load_policy("stop_when_blocked", env), EPISODES,
                         int(params.max_steps), record_lanes=[2, 0])(key, params)
    leaves_equal(some.values, every.values)
    leaves_equal(some.states, jax.tree.map(lambda leaf: leaf[:, [2, 0]], every.states))
    assert np.shape(some.states.time) == (int(params.max_steps) + 1, 2)
    with pytest.raises(ValueError, match="give one"):
        EpisodeRunner(env, only_local(env), 3, 10, record=True, record_lanes=[0])
    with pytest.raises(ValueError, match=r"indices in \[0, 3\)"):
        EpisodeRunner(env, only_local(env), 3, 10, record_lanes=[3])
    with pytest.raises(ValueError, match="pairs"):
        LaneRunner(env, [only_local(env)], 1, 3, 10, record_lanes=[(1, 0)])


def _go_with_chance(lane):
    """GO with chance ``lane["go"]`` each step (reads the per-step keys)."""
    return lambda obs, key, state, params: jax.random.bernoulli(
        key, lane["go"], obs.shape[:1]).astype(jnp.int32)


def _stop_every(lane):
    """A policy with memory: counts its steps and STOPs every ``lane["period"]``-th one
    (reads its memory, which each lane must keep apart)."""
    def step(count, obs, key, state, params):
        count = count + 1
        return count, (count % lane["period"] != 0).astype(jnp.int32)

    return RecurrentPolicy(init=lambda num_robots: jnp.zeros(num_robots, jnp.int32), step=step)


@pytest.mark.parametrize("make_policy, lanes", [
    (_go_with_chance, {"go": jnp.array([0.2, 0.9, 0.6])}),
    pytest.param(_stop_every, {"period": jnp.array([2, 5, 3])}, marks=pytest.mark.slow)],
    ids=["stateless", "memory"])
def test_param_lanes_play_the_episodes_of_separate_runs(make_policy, lanes):
    """Lane ``l`` of a ``ParamLaneRunner`` (inside the ``jit`` that takes the lanes' parameters)
    plays the episodes an ``EpisodeRunner`` of lane ``l``'s policy plays with the same key;
    the lanes differ from one another, so a mix-up of lanes would show."""
    env, by_count = params_by_count(SCENARIO, [3], options=OPTIONS.replace(time_limit=8.0))
    params, key, steps = by_count[3], jax.random.key(SEED), int(by_count[3].max_steps)

    @jax.jit
    def together(lanes, key, params):
        return ParamLaneRunner(env, make_policy, lanes, EPISODES, steps).episodes(key, params)

    values, robot, states, rewards = together(lanes, key, params)
    assert states is None and rewards is None and values["success"].shape == (3, EPISODES)
    assert robot["success"].shape == (3, EPISODES, env.max_agents)

    @jax.jit
    def alone(lane, key, params):  # one lane's parameters traced: one program for the three
        return EpisodeRunner(env, make_policy(lane), EPISODES, steps).episodes(key, params)

    for lane in range(3):
        separate, separate_robot, *_ = alone(jax.tree.map(lambda v, i=lane: v[i], lanes), key,
                                            params)
        for ours, theirs in ((values, separate), (robot, separate_robot)):
            assert ours.keys() == theirs.keys()
            for name in theirs:
                np.testing.assert_allclose(ours[name][lane], theirs[name], rtol=1e-6, atol=0,
                                           err_msg=f"lane {lane}: {name}")
    progress = np.asarray(values["path_length"])
    assert not np.allclose(progress[0], progress[1]), "the lanes played alike"
    with pytest.raises(ValueError, match="same leading lanes axis"):
        ParamLaneRunner(env, make_policy, {"go": jnp.zeros(3), "x": jnp.zeros(2)}, 1, steps)
