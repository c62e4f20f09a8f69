"""The PettingZoo adapter passes PettingZoo's own checkers and is deterministic per seed."""

import gymnasium
import numpy as np
import pytest
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test
from pettingzoo.utils.conversions import parallel_to_aec

from sgjax.adapters.pettingzoo import parallel_env


@pytest.mark.parametrize("action_mode", ["go_stop", "continuous"])
def test_parallel_api(action_mode):
    parallel_api_test(parallel_env("open", num_agents=3, action_mode=action_mode), num_cycles=800)


def test_parallel_seed():
    parallel_seed_test(lambda: parallel_env("doorway", num_agents=3), num_cycles=100)


def test_aec_api_through_parallel_to_aec():
    api_test(parallel_to_aec(parallel_env("hallway", num_agents=2)), num_cycles=200)


def run_episode(seed):
    env = parallel_env("doorway", num_agents=3)
    obs, _ = env.reset(seed=seed)
    for agent in env.possible_agents:
        env.action_space(agent).seed(seed)
    history = [obs]
    while env.agents:
        actions = {a: env.action_space(a).sample() for a in env.agents}
        out = env.step(actions)
        history.append(out)
    return history


@pytest.mark.slow
def test_whole_episode_is_deterministic_per_seed():
    a, b, c = run_episode(5), run_episode(5), run_episode(6)
    assert len(a) == len(b) > 10
    for step_a, step_b in zip(a, b, strict=True):
        assert repr(step_a) == repr(step_b)
    assert repr(a[:3]) != repr(c[:3])


def test_boundary_types_and_lifecycle():
    env = parallel_env("open", num_agents=2, render_mode="rgb_array")
    assert env.possible_agents == ["robot_0", "robot_1"]
    assert env.metadata["name"] == "sgjax_v0" and "rgb_array" in env.metadata["render_modes"]
    obs, infos = env.reset(seed=0)
    assert isinstance(env.observation_space("robot_0"), gymnasium.spaces.Box)
    assert obs["robot_0"].dtype == np.float32 and env.observation_space("robot_0").contains(
        obs["robot_0"])
    assert infos["robot_0"] is not infos["robot_1"]
    finished = set()
    while env.agents:
        o, r, te, tr, info = env.step({a: 0 for a in env.agents})
        assert all(isinstance(v, float) for v in r.values())
        assert all(type(v) is bool for v in list(te.values()) + list(tr.values()))
        finished |= {a for a in te if te[a] or tr[a]}
        assert not finished & set(env.agents)  # removed right after, never revived
    assert env.step({}) == ({}, {}, {}, {}, {})
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert env.state().shape == (2 * 10,)


def test_bad_actions_are_named():
    env = parallel_env("open", num_agents=2)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="robot_0"):
        env.step({"robot_0": 7, "robot_1": 0})
    with pytest.raises(ValueError, match="not live"):
        env.step({"robot_9": 0})
    continuous = parallel_env("open", num_agents=2, action_mode="continuous")
    continuous.reset(seed=0)
    with pytest.raises(ValueError, match=r"action \[nan, 0.0\] for robot_1 is not finite"):
        continuous.step({"robot_0": [0.0, 0.0], "robot_1": [float("nan"), 0.0]})
