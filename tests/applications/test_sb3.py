"""Stable-Baselines3: the SuperSuit route carries the PettingZoo env step for step and PPO
trains through it; PPO learns through the native batched VecEnv (success rises from zero on the
open space with continuous actions)."""

import numpy as np
import pytest

# Set by `libraries` when the file's first test runs.
sb3 = torch = set_random_seed = SgjaxVecEnv = supersuit_vec_env = None


@pytest.fixture(scope="module", autouse=True)
def libraries():
    """Stable-Baselines3, SuperSuit, torch and sgjax's SB3 adapter, imported when this file's
    first test runs instead of when it is collected (every xdist worker collects every file,
    and importing torch takes about 1.1 s), or a skip that names what to install."""
    global sb3, torch, set_random_seed, SgjaxVecEnv, supersuit_vec_env
    sb3 = pytest.importorskip("stable_baselines3",
                              reason="pip install torch==2.13.0, then .[sb3]")
    pytest.importorskip("supersuit")
    torch = pytest.importorskip("torch")
    from stable_baselines3.common.utils import set_random_seed

    from sgjax.adapters.sb3 import SgjaxVecEnv, supersuit_vec_env

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


def test_the_supersuit_route_ends_episodes_together_under_black_death():
    """SuperSuit's vector env (SocialGym 2.0's route): one row per robot in agent order; a robot
    that finishes early sees zeros with reward 0 (black death) and every row is done together,
    at the time limit when nobody arrives."""
    kwargs = dict(scenario="open", num_agents=2, action_mode="continuous", time_limit=3.0)
    venv = supersuit_vec_env(seed=0, **kwargs)
    obs = venv.reset()
    assert obs.shape == (2, 10) and np.all(np.any(obs != 0.0, axis=1))
    still = np.zeros((2, 2), np.float32)  # nobody moves: nobody arrives
    ends = []
    for t in range(70):
        obs, reward, done, _ = venv.step(still)
        assert done[0] == done[1] and np.all(np.isfinite(reward)), t
        if done.any():
            ends.append(t + 1)
    # SuperSuit's black death reports the end one step after the environment's last step.
    assert np.diff([0, *ends]).tolist() == [31, 31], ends
    # Moving robots: whoever finishes first sees zeros until the other is done.
    venv = supersuit_vec_env(seed=3, scenario="open", num_agents=2, time_limit=20.0)
    venv.reset()
    go = np.zeros(2, np.int64)
    for _ in range(200):
        obs, reward, done, _ = venv.step(go)
        dead = ~np.any(obs != 0.0, axis=1)
        if done.any():
            break
        assert np.all(reward[dead] == 0.0)
    assert done.all()


@pytest.fixture(autouse=True)
def sb3_logs_in_tmp_path(tmp_path, monkeypatch):
    """SB3's default logger makes an empty ``SB3-<date>`` folder in the system's temporary
    folder on every ``learn``; ``SB3_LOGDIR`` puts it in the test's own folder instead."""
    monkeypatch.setenv("SB3_LOGDIR", str(tmp_path / "sb3"))


@pytest.mark.slow
def test_ppo_trains_through_the_supersuit_route():
    """PPO runs updates on the route (learning itself is shown through the native VecEnv below,
    which carries the same environment faster)."""
    kwargs = dict(scenario="open", num_agents=2, action_mode="continuous", time_limit=15.0)
    set_random_seed(0)  # no seed= for PPO: SuperSuit's ConcatVecEnv has no seed()
    model = sb3.PPO("MlpPolicy", supersuit_vec_env(seed=0, **kwargs), n_steps=256,
                    batch_size=128, n_epochs=2)
    before = [p.detach().clone() for p in model.policy.parameters()]
    model.learn(1024)
    assert model.num_timesteps >= 1024
    assert any(not torch.equal(a, b) for a, b in zip(before, model.policy.parameters(),
                                                         strict=True))


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
    bad = stop.copy()
    bad[3] = 5  # world 1, robot slot 1
    with pytest.raises(ValueError, match=r"step_async: robot slot 1 of batch index 1 has action "
                                         r"5; GO/STOP actions are 0 \(GO\) or 1 \(STOP\)"):
        venv.step(bad)


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
