"""Stable-Baselines3 routes: a native batched ``VecEnv`` and the SuperSuit pipeline.

Native (fast)::

    from sgjax.adapters.sb3 import SgjaxVecEnv
    venv = SgjaxVecEnv("doorway", num_agents=4, num_envs=64)   # 256 SB3 slots
    model = stable_baselines3.PPO("MlpPolicy", venv).learn(100_000)

Every robot of ``num_envs`` batched environments is one SB3 slot; one jitted ``vmap(step)``
steps them all. A slot reports ``done`` on the step its robot finishes (goal reached:
``infos[i]["is_success"]``; time limit: ``TimeLimit.truncated``), with
``infos[i]["terminal_observation"]``.
Until its environment resets (when every robot is done) the slot sees zeros and reward 0, as with
SuperSuit's ``black_death_v3``; the reset ends that dead stretch with one more ``done``.

SuperSuit (what SocialGym 2.0 users ran; slower, one environment)::

    venv = supersuit_vec_env("doorway", num_agents=4)

Install ``torch==2.13.0`` before ``pip install -e ".[sb3]"`` (see docs/interop.md).
"""

from __future__ import annotations

from typing import Any

import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from sgjax.environment.env import reject_invalid_actions
from sgjax.environment.registry import make


class SgjaxVecEnv(VecEnv):
    """All robots of ``num_envs`` sgjax environments as one SB3 ``VecEnv``."""

    def __init__(self, scenario: str = "doorway", num_agents: int = 4, num_envs: int = 16,
                 seed: int = 0, **overrides: Any):
        if "max_agents" in overrides:
            raise TypeError("SgjaxVecEnv: max_agents is num_agents here")
        self.env, self.params = make(scenario, num_agents=num_agents, **overrides)
        self.num_worlds, self.num_robots = num_envs, num_agents
        self.render_mode = None
        super().__init__(num_envs * num_agents, self.env.observation_space(self.params),
                         self.env.action_space(self.params))
        self._discrete = isinstance(self.action_space, gymnasium.spaces.Discrete)
        vstep = self.env.step_batch  # vmap(step), resetting only the ended worlds
        vreset = jax.vmap(self.env.reset, in_axes=(0, None))
        self._reset_fn = jax.jit(lambda key, p: vreset(jax.random.split(key, num_envs), p))
        self._step_fn = jax.jit(self._step_batch(vstep))
        self._key = jax.random.key(seed)
        self._state = None
        self._actions = None

    def _step_batch(self, vstep):
        num_envs = self.num_worlds

        def step(key, state, actions, params):
            active = state.robots.active
            obs, state, reward, terminated, truncated, info = vstep(
                jax.random.split(key, num_envs), state, actions, params)
            finished = active & (terminated | truncated)
            # Slots whose robot finished earlier get one more done when their world resets.
            dead = ~active & info["episode_done"][:, None]
            live_next = state.robots.active | info["episode_done"][:, None]
            obs = jnp.where(live_next[..., None], obs, 0.0)
            final = jnp.where(active[..., None], info["final_observation"], 0.0)
            return (obs, state, reward, finished | dead, finished & truncated & ~terminated,
                    final, active & info["arrived"])

        return step

    # ------------------------------------------------------------------ VecEnv API
    def reset(self) -> np.ndarray:
        self._key, key = jax.random.split(self._key)
        obs, self._state = self._reset_fn(key, self.params)
        return np.array(obs, np.float32).reshape(self.num_envs, -1)

    def step_async(self, actions: np.ndarray) -> None:
        actions = np.asarray(actions)
        if self._discrete:
            actions = actions.reshape(self.num_worlds, self.num_robots)
        else:
            actions = actions.reshape(self.num_worlds, self.num_robots, -1)
        # an error naming the world (batch index) and robot slot: NaN or out of range
        reject_invalid_actions(actions, not self._discrete, "step_async")
        self._actions = jnp.asarray(actions, jnp.int32 if self._discrete else jnp.float32)

    def step_wait(self):
        if self._state is None:
            raise RuntimeError("step before reset")
        self._key, key = jax.random.split(self._key)
        obs, self._state, reward, done, truncated, final, success = self._step_fn(
            key, self._state, self._actions, self.params)
        # Copies: SB3 writes into these arrays, and views of JAX arrays are read-only.
        obs = np.array(obs, np.float32).reshape(self.num_envs, -1)
        done = np.array(done).reshape(-1)
        truncated = np.asarray(truncated).reshape(-1)
        final = np.asarray(final, np.float32).reshape(self.num_envs, -1)
        success = np.asarray(success).reshape(-1)
        infos: list[dict] = [{} for _ in range(self.num_envs)]
        for i in np.flatnonzero(done):
            infos[i] = {"terminal_observation": final[i], "TimeLimit.truncated": bool(truncated[i]),
                        "is_success": bool(success[i])}
        return obs, np.array(reward, np.float32).reshape(-1), done, infos

    def close(self) -> None:
        self._state = None

    def get_attr(self, attr_name: str, indices=None) -> list:
        return [getattr(self, attr_name)] * len(self._indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        setattr(self, attr_name, value)

    def env_method(self, method_name: str, *args, indices=None, **kwargs) -> list:
        return [getattr(self, method_name)(*args, **kwargs)] * len(self._indices(indices))

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False] * len(self._indices(indices))

    def seed(self, seed: int | None = None) -> list:
        if seed is not None:
            self._key = jax.random.key(seed)
        return [seed] * self.num_envs

    def _indices(self, indices) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        return [indices] if isinstance(indices, int) else list(indices)


def supersuit_vec_env(scenario: str = "doorway", num_agents: int = 4, seed: int | None = None,
                      **overrides: Any):
    """SocialGym 2.0's route: PettingZoo env -> SuperSuit black death -> SB3 VecEnv.

    ``num_cpus=0``: SuperSuit's multiprocessing forks, which is unsafe once JAX has started.
    ``seed`` seeds the episodes (SB3 cannot: SuperSuit's vector env has no ``seed``). Black death
    keeps a finished robot in play with zero observations until every robot is done, so its
    success never reaches SB3's infos; count episodes or use the native ``SgjaxVecEnv``.
    """
    import supersuit as ss

    from sgjax.adapters.pettingzoo import parallel_env

    env = ss.black_death_v3(parallel_env(scenario, num_agents=num_agents, seed=seed, **overrides))
    env = ss.pettingzoo_env_to_vec_env_v1(env)
    return ss.concat_vec_envs_v1(env, 1, num_cpus=0, base_class="stable_baselines3")
