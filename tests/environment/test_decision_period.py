"""``make(..., decision_period=k)``: robots read actions every ``k`` steps and hold them in
between; the trainer's actor learns only from the steps whose action was read."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scenes import go_run_counting_traces

import sgjax
from train.algorithm.config import config_from_dict
from train.algorithm.trainer import Trainer

STOP = 1


def _forward_speeds(period, requests, steps=12):
    """Robot 0's forward speed after each step when it asks STOP at the steps in
    ``requests`` and GO otherwise; with the step's ``decided`` and held action."""
    env, params = sgjax.make("open", num_agents=2, decision_period=period)
    _, state = env.reset(jax.random.key(0), params)
    step = jax.jit(env.step_env)
    rows = []
    for t in range(steps):
        actions = jnp.array([STOP if t in requests else 0, 0])
        _, state, _, _, _, info = step(jax.random.key(t), state, actions, params)
        rows.append((bool(info["decided"]), int(state.held_action[0]),
                     float(state.robots.kin.v_forward[0])))
    return rows


def test_actions_are_read_every_period_and_held_in_between():
    rows = _forward_speeds(5, requests={1, 2, 3, 5})
    decided = [d for d, _, _ in rows]
    assert decided == [t % 5 == 0 for t in range(12)]
    held = [h for _, h, _ in rows]
    # The STOPs asked at steps 1-3 fall between decisions: ignored. The one at 5 is read and
    # held through step 9 although GO is asked at 6-9; GO again at 10.
    assert held == [0] * 5 + [STOP] * 5 + [0] * 2
    speeds = [v for _, _, v in rows]
    assert speeds[4] > 1.0 and speeds[7] == speeds[8] == speeds[9] == 0.0 and speeds[11] > 0.0
    # Every step reads its action with period 1: the STOPs at 1-3 slow the robot down at once.
    every = _forward_speeds(1, requests={1, 2, 3, 5})
    assert all(d for d, _, _ in every) and every[3][2] < rows[3][2]


def test_a_held_run_equals_period_one_fed_the_held_actions():
    """Random GO/STOP requests under period 3 give, step by step, the same episode as period 1
    given the actions in force (the held ones), through an auto-reset: the same observations
    and positions bit for bit, the same rewards to float rounding (the two programs compile
    the route progress behind the reward in different fusions: up to 2e-6 m apart)."""
    held_env, params = sgjax.make("doorway", num_agents=3, decision_period=3, time_limit=6.0)
    plain_env, _ = sgjax.make("doorway", num_agents=3, time_limit=6.0)
    _, held = held_env.reset(jax.random.key(4), params)
    plain = held.replace()
    held_step, plain_step = jax.jit(held_env.step), jax.jit(plain_env.step)
    ends = 0
    for t in range(80):
        key = jax.random.key(100 + t)
        requests = jax.random.bernoulli(jax.random.key(t), 0.4, (3,)).astype(jnp.int32)
        in_force = jnp.where(held.time % 3 == 0, requests, held.held_action)
        obs_h, held, reward_h, _, _, info = held_step(key, held, requests, params)
        obs_p, plain, reward_p, _, _, _ = plain_step(key, plain, in_force, params)
        ends += int(info["episode_done"])
        np.testing.assert_array_equal(obs_h, obs_p)
        np.testing.assert_allclose(reward_h, reward_p, rtol=0, atol=1e-5)
        np.testing.assert_array_equal(held.robots.x, plain.robots.x)
    assert ends >= 1


def test_holding_does_not_retrace_across_decisions_and_episodes():
    env, params = sgjax.make("open", num_agents=2, decision_period=4, time_limit=3.0)
    visited, traces = go_run_counting_traces(env, params, 40)
    assert any(bool(info["episode_done"]) for _, info in visited) and traces == 1


def test_bad_decision_periods_are_errors_naming_the_option():
    for bad in (0, -2, 1.5, True):
        with pytest.raises(ValueError, match="decision_period must be a positive integer"):
            sgjax.make("open", num_agents=2, decision_period=bad)


def _loss_terms(trainer, runner, flip):
    """The PPO loss terms of one rollout (from the episodes' start), with the actions of the
    steps ``t % 4 != 0`` flipped (GO <-> STOP) when ``flip``."""
    runner, rollout, _ = jax.jit(trainer.collect)(runner)
    traj = rollout.traj
    if flip:
        between = (jnp.arange(traj.action.shape[0]) % 4 != 0)[:, None]
        traj = traj.replace(action=jnp.where(between, 1 - traj.action, traj.action))
    _, aux = trainer.learner.loss(runner.params, rollout.memory, traj, rollout.advantages,
                           rollout.targets)
    return traj, aux


@pytest.mark.slow
@pytest.mark.parametrize("period", [1, 4])
def test_the_actor_learns_only_from_the_actions_the_environment_read(period):
    """Under period 4 the actions between decisions change no loss term; under period 1 the
    same steps are decisions and the terms that read the action change (entropy and the
    critic's never do)."""
    config = config_from_dict({
        "env": {"scenarios": ["doorway"], "curriculum": [[0, 3]], "decision_period": period},
        "algorithm": {"num_envs": 4, "num_steps": 12, "total_steps": 48},
        "network": {"hidden": [16]}}, "test")
    trainer = Trainer(config)
    runner = trainer.init(jax.random.PRNGKey(0))
    traj, same = _loss_terms(trainer, runner, False)
    _, flipped = _loss_terms(trainer, runner, True)
    assert float(jnp.mean(traj.decides)) == pytest.approx(1.0 if period == 1 else 3 / 12)
    for name in ("policy_loss", "entropy", "approx_kl", "value_loss"):
        if period == 1 and name in ("policy_loss", "approx_kl"):
            assert float(same[name]) != float(flipped[name]), name
        else:
            assert float(same[name]) == float(flipped[name]), name
