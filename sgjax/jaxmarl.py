"""A JaxMARL-compatible surface over an sgjax environment (dicts at the edge, dense inside).

JaxMARL's baselines (IPPO, MAPPO) drive environments through ``agents``, ``num_agents``,
``observation_space(agent)``, ``action_space(agent)``, ``reset(key) -> (obs, state)`` and
``step(key, state, actions) -> (obs, state, rewards, dones, infos)`` with dicts keyed by agent,
``dones["__all__"]`` and auto-reset; everything is jittable and vmappable::

    env = SocialNavJaxMARL("doorway", num_agents=4)
    obs, state = env.reset(jax.random.key(0))
    actions = {a: env.action_space(a).sample(k) for a, k in zip(env.agents, keys)}
    obs, state, rewards, dones, infos = env.step(jax.random.key(1), state, actions)

``dones[agent]`` is terminated or truncated; ``infos`` holds ``terminated``, ``truncated``
(``[R]``), the final observation of an ended episode, and ``world_state`` for centralised
critics (every robot's observation, concatenated).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.env import EnvParams, EnvState
from sgjax.registry import make


@struct.dataclass
class Discrete:
    """JaxMARL-style discrete space: actions ``0 .. n-1``."""

    n: int = struct.field(pytree_node=False)
    shape: tuple = struct.field(pytree_node=False, default=())
    dtype: Any = struct.field(pytree_node=False, default=jnp.int32)

    def sample(self, key: Array) -> Array:
        return jax.random.randint(key, self.shape, 0, self.n, self.dtype)


@struct.dataclass
class Box:
    """JaxMARL-style box space."""

    low: float = struct.field(pytree_node=False)
    high: float = struct.field(pytree_node=False)
    shape: tuple = struct.field(pytree_node=False)
    dtype: Any = struct.field(pytree_node=False, default=jnp.float32)

    def sample(self, key: Array) -> Array:
        low = max(self.low, -1.0) if self.low == -jnp.inf else self.low
        high = min(self.high, 1.0) if self.high == jnp.inf else self.high
        return jax.random.uniform(key, self.shape, self.dtype, low, high)


class SocialNavJaxMARL:
    """JaxMARL ``MultiAgentEnv``-style wrapper; agents are ``robot_0 ... robot_{n-1}``."""

    def __init__(self, scenario: str = "doorway", num_agents: int = 4,
                 params: EnvParams | None = None, **overrides: Any):
        if "max_agents" in overrides:
            raise TypeError("SocialNavJaxMARL: max_agents is num_agents here (JaxMARL agents are "
                            "fixed per environment)")
        self.env, default_params = make(scenario, num_agents=num_agents, **overrides)
        self.params = default_params if params is None else params
        self.num_agents = num_agents
        self.agents = [f"robot_{i}" for i in range(num_agents)]
        obs_space = self.env.observation_space(self.params)
        act_space = self.env.action_space(self.params)
        observation = Box(-jnp.inf, jnp.inf, obs_space.shape)
        if hasattr(act_space, "n"):
            action = Discrete(int(act_space.n))
        else:
            action = Box(-1.0, 1.0, act_space.shape)
        self.observation_spaces = {a: observation for a in self.agents}
        self.action_spaces = {a: action for a in self.agents}

    def observation_space(self, agent: str) -> Box:
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> Discrete | Box:
        return self.action_spaces[agent]

    def _to_dict(self, stacked: Array) -> dict[str, Array]:
        return {a: stacked[i] for i, a in enumerate(self.agents)}

    def reset(self, key: Array) -> tuple[dict[str, Array], EnvState]:
        obs, state = self.env.reset(key, self.params)
        return self._to_dict(obs), state

    def step(
        self, key: Array, state: EnvState, actions: dict[str, Array]
    ) -> tuple[dict, EnvState, dict, dict, dict]:
        stacked = jnp.stack([jnp.asarray(actions[a]) for a in self.agents])
        obs, state, reward, terminated, truncated, info = self.env.step(
            key, state, stacked, self.params)
        done = terminated | truncated
        dones = self._to_dict(done)
        dones["__all__"] = info["episode_done"]
        infos = {
            "terminated": terminated,
            "truncated": truncated,
            "final_observation": info["final_observation"],
            "world_state": obs.reshape(-1),
        }
        return self._to_dict(obs), state, self._to_dict(reward), dones, infos

    def get_avail_actions(self, state: EnvState) -> dict[str, Array]:
        """Every action is always available."""
        space = self.action_spaces[self.agents[0]]
        size = space.n if isinstance(space, Discrete) else space.shape[0]
        return {a: jnp.ones(size) for a in self.agents}
