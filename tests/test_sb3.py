"""Stable-Baselines3: PPO trains through the SuperSuit route and learns through the native
batched VecEnv (success rises from zero on the open space with continuous actions)."""

import numpy as np
import pytest

sb3 = pytest.importorskip("stable_baselines3", reason="pip install torch==2.13.0, then .[sb3]")
pytest.importorskip("supersuit")
torch = pytest.importorskip("torch")

from stable_baselines3.common.utils import set_random_seed  # noqa: E402

from sgjax.sb3 import SgjaxVecEnv, supersuit_vec_env  # noqa: E402

torch.set_num_threads(1)


def evaluate(model, venv, steps):
    """(robot episodes ended, robots that reached their goal) under the deterministic policy."""
    obs = venv.reset()
    ended = reached = 0
    for _ in range(steps):
        action, _ = model.predict(obs, deterministic=True)
        obs, _, done, infos = venv.step(action)
        ended += int(done.sum())
        reached += sum(infos[i].get("is_success", False) for i in np.flatnonzero(done))
    return ended, reached


@pytest.mark.slow
def test_ppo_learns_through_the_supersuit_route():
    # Black death hides per-robot success from SB3 (see supersuit_vec_env), so learning shows
    # as shorter episodes: before training every episode runs into the 15 s time limit.
    kwargs = dict(scenario="open", num_agents=2, action_mode="continuous", time_limit=15.0)
    # No seed= for PPO: SB3 would call venv.seed(), which SuperSuit's ConcatVecEnv lacks. Seed
    # python, numpy (PPO's minibatch order) and torch ourselves so the run is order-independent.
    set_random_seed(0)
    model = sb3.PPO("MlpPolicy", supersuit_vec_env(seed=0, **kwargs), n_steps=512,
                    batch_size=256)
    before, _ = evaluate(model, supersuit_vec_env(seed=1, **kwargs), 1500)
    # 40k steps gave 18 -> 24 episodes after this session's float changes (a thin margin);
    # 60k gives 18 -> 46 for 5 s more.
    model.learn(60_000)
    after, _ = evaluate(model, supersuit_vec_env(seed=1, **kwargs), 1500)
    assert before <= 20 and after >= 1.5 * before, (before, after)


def test_native_vec_env_shapes_and_done_semantics():
    venv = SgjaxVecEnv("open", num_agents=2, num_envs=3, time_limit=2.0)
    obs = venv.reset()
    assert obs.shape == (6, 10) and obs.dtype == np.float32
    stop = np.ones(6, dtype=np.int64)
    for t in range(20):
        obs, reward, done, infos = venv.step(stop)
        if t < 19:
            assert not done.any()
    # STOP for 2 s: every robot is truncated at step 20, with its final observation.
    assert done.all()
    assert all(info["TimeLimit.truncated"] and not info["is_success"] for info in infos)
    assert all(info["terminal_observation"].shape == (10,) for info in infos)
    assert reward.dtype == np.float32 and reward.flags.writeable


@pytest.mark.slow
def test_ppo_learns_through_native_vec_env():
    kwargs = dict(scenario="open", num_agents=2, num_envs=16, action_mode="continuous",
                  time_limit=15.0)
    model = sb3.PPO("MlpPolicy", SgjaxVecEnv(seed=0, **kwargs), n_steps=64, batch_size=256,
                    seed=0)
    _, before = evaluate(model, SgjaxVecEnv(seed=1, **kwargs), 300)
    model.learn(30_000)
    _, after = evaluate(model, SgjaxVecEnv(seed=1, **kwargs), 300)
    assert before <= 2 and after >= 20, (before, after)
