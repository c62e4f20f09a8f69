"""PettingZoo ``ParallelEnv`` adapter: one jitted sgjax environment, numpy at the boundary.

    from sgjax.adapters.pettingzoo import parallel_env
    env = parallel_env(scenario="doorway", num_agents=4)
    obs, infos = env.reset(seed=0)
    while env.agents:
        actions = {agent: env.action_space(agent).sample() for agent in env.agents}
        obs, rewards, terminations, truncations, infos = env.step(actions)

Agents are ``robot_0 ... robot_{n-1}``. Observations are ``numpy.float32`` arrays inside a
``gymnasium.spaces.Box``, rewards Python floats, terminations and truncations Python bools, and
every agent gets a fresh info dict. A robot is removed from ``agents`` right after the step that
reports it terminated (goal reached) or truncated (time limit) and is never revived; after the
last one, ``step({})`` returns five empty dicts until ``reset``. ``reset(seed=...)`` is
deterministic; without a seed the next episode's key comes from the adapter's own generator
(seeded by the last seed given, or by ``parallel_env(seed=...)``).
"""

from __future__ import annotations

from typing import Any

import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
from pettingzoo import ParallelEnv

from sgjax.environment.registry import make
from sgjax.evaluation.render import render_state
from sgjax.maps.io import load

RENDER_FPS = 10


class SgjaxParallelEnv(ParallelEnv):
    """A PettingZoo ``ParallelEnv`` over one sgjax environment (see the module docstring)."""

    metadata = {"name": "sgjax_v0", "render_modes": ["rgb_array"], "render_fps": RENDER_FPS,
                "is_parallelizable": True}

    def __init__(self, scenario: str = "doorway", num_agents: int = 4,
                 render_mode: str | None = None, seed: int | None = None, **overrides: Any):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of "
                             f"{self.metadata['render_modes']}, got {render_mode!r}")
        if "max_agents" in overrides:
            raise TypeError("parallel_env: max_agents is num_agents here (PettingZoo agents are "
                            "fixed per environment)")
        self.env, self.params = make(scenario, num_agents=num_agents, **overrides)
        self.scenario = scenario
        self.render_mode = render_mode
        self.possible_agents = [f"robot_{i}" for i in range(num_agents)]
        self.agents: list[str] = []
        self._index = {agent: i for i, agent in enumerate(self.possible_agents)}
        self._observation_space = self.env.observation_space(self.params)
        self._action_space = self.env.action_space(self.params)
        self._observation_spaces = {a: self._observation_space for a in self.possible_agents}
        self._action_spaces = {a: self._action_space for a in self.possible_agents}
        self._reset = jax.jit(self.env.reset)
        self._step = jax.jit(self.env.step_env)
        self._rng = np.random.default_rng(seed)
        self._key = jax.random.key(0)
        self._state = None
        self._map = None
        self._trail: list[np.ndarray] = []

    # PettingZoo asks for the very same space object on every call.
    def observation_space(self, agent: str) -> gymnasium.spaces.Space:
        return self._observation_spaces[agent]

    def action_space(self, agent: str) -> gymnasium.spaces.Space:
        return self._action_spaces[agent]

    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        key_seed = int(self._rng.integers(0, 2**31 - 1))
        self._key, reset_key = jax.random.split(jax.random.key(key_seed))
        previous = self._state
        obs, self._state = self._reset(reset_key, self.params)
        if previous is not None:  # reward-weight schedules count steps across episodes
            self._state = self._state.replace(total_steps=previous.total_steps)
        self.agents = [a for a in self.possible_agents
                       if bool(self._state.robots.present[self._index[a]])]
        self._trail = [np.asarray(self._state.robots.position)]
        obs = np.asarray(obs, dtype=np.float32)
        return ({a: obs[self._index[a]] for a in self.agents},
                {a: {} for a in self.agents})

    def step(self, actions: dict[str, Any]):
        if not self.agents:
            return {}, {}, {}, {}, {}
        unknown = set(actions) - set(self.agents)
        if unknown:
            raise ValueError(f"step: actions for agents that are not live: {sorted(unknown)}; "
                             f"live agents are {self.agents}")
        batch = self._action_array(actions)
        self._key, step_key = jax.random.split(self._key)
        obs, self._state, reward, terminated, truncated, info = self._step(
            step_key, self._state, batch, self.params)
        obs = np.asarray(obs, dtype=np.float32)
        reward, terminated = np.asarray(reward), np.asarray(terminated)
        truncated = np.asarray(truncated)
        robot_hit = np.asarray(info["collision_robot"])
        wall_hit = np.asarray(info["collision_wall"])
        human_hit = np.asarray(info["collision_human"])
        succeeded = np.asarray(self._state.robots.succeeded)
        terms_by_name = {k: np.asarray(v) for k, v in info["reward_terms"].items()}
        live = self.agents
        out_obs, rewards, terms, truncs, infos = {}, {}, {}, {}, {}
        for agent in live:
            i = self._index[agent]
            out_obs[agent] = obs[i]
            rewards[agent] = float(reward[i])
            terms[agent] = bool(terminated[i])
            truncs[agent] = bool(truncated[i])
            infos[agent] = {"collision_robot": bool(robot_hit[i]),
                            "collision_wall": bool(wall_hit[i]),
                            "collision_human": bool(human_hit[i]),
                            "is_success": bool(succeeded[i]),
                            "reward_terms": {k: float(v[i]) for k, v in terms_by_name.items()}}
        self.agents = [a for a in live if not (terms[a] or truncs[a])]
        self._trail.append(np.asarray(self._state.robots.position))
        return out_obs, rewards, terms, truncs, infos

    def _action_array(self, actions: dict[str, Any]) -> jax.Array:
        """Stack per-agent actions; robots without an action (finished) get STOP / zeros."""
        n = len(self.possible_agents)
        space = self._action_space
        if isinstance(space, gymnasium.spaces.Discrete):
            batch = np.ones(n, dtype=np.int32)  # STOP
            for agent, action in actions.items():
                if np.ndim(action) != 0 or int(action) != action or not 0 <= int(action) < 2:
                    raise ValueError(f"step: action {action!r} for {agent} is not in {space} "
                                     "(0 = GO, 1 = STOP)")
                batch[self._index[agent]] = int(action)
            return jnp.asarray(batch)
        batch = np.zeros((n, *space.shape), dtype=np.float32)
        for agent, action in actions.items():
            value = np.asarray(action, dtype=np.float32)
            if value.shape != space.shape:
                raise ValueError(f"step: action for {agent} must have shape {space.shape}, "
                                 f"got {value.shape}")
            if not np.all(np.isfinite(value)):
                raise ValueError(f"step: action {value.tolist()} for {agent} is not finite "
                                 "(continuous actions must be finite)")
            batch[self._index[agent]] = value
        return jnp.asarray(batch)

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gymnasium.logger.warn("render() called without render_mode='rgb_array'")
            return None
        if self._state is None:
            raise RuntimeError("render() before reset()")
        if self._map is None:
            self._map = load(self.scenario) if isinstance(self.scenario, str) else self.scenario
        return render_state(self._map, self._state, self.params.robots.radius,
                            trail=np.stack(self._trail[-15:]),
                            title=f"{self.env.config.scenario}  step {int(self._state.time)}")

    def state(self) -> np.ndarray:
        """Global state for centralised critics: every robot's observation, concatenated."""
        if self._state is None:
            raise RuntimeError("state() before reset()")
        return np.asarray(self.env.observe(self._state, self.params), np.float32).reshape(-1)

    def close(self) -> None:
        self._state = None


def parallel_env(scenario: str = "doorway", num_agents: int = 4,
                 render_mode: str | None = None, seed: int | None = None,
                 **overrides: Any) -> SgjaxParallelEnv:
    """A PettingZoo ``ParallelEnv`` over ``sgjax.make(scenario, num_agents=..., **overrides)``.

    ``seed`` seeds the generator that picks episodes when ``reset`` gets no seed of its own
    (wrappers such as SuperSuit's reset without one).
    """
    return SgjaxParallelEnv(scenario, num_agents=num_agents, render_mode=render_mode, seed=seed,
                            **overrides)
