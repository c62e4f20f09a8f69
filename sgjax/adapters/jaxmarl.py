"""sgjax's mini-games as JaxMARL environments (``pip install 'sgjax[jaxmarl]'``).

:class:`SocialNavJaxMARL` is a JaxMARL ``MultiAgentEnv`` (jaxmarl 0.2): JaxMARL's spaces, dicts
keyed by agent (``robot_0 ... robot_{n-1}``), ``reset(key) -> (obs, state)``,
``step(key, state, actions, reset_state=None) -> (obs, state, rewards, dones, infos)`` with
``dones["__all__"]`` and auto-reset (to ``reset_state`` when given), ``step_env`` without it,
``get_obs``, boolean ``get_avail_actions``; jittable and vmappable. One line, as with
``jaxmarl.make``::

    from sgjax.adapters.jaxmarl import make_jaxmarl
    env = make_jaxmarl("sgjax_doorway", num_agents=4)          # or SocialNavJaxMARL("doorway", 4)

What JaxMARL's baselines expect, and what this adapter does:

- an agent's action may come as ``()`` or ``(1,)`` (discrete) and ``(d,)`` or ``(1, d)``
  (continuous), as their ``unbatchify`` leaves it;
- every ``infos`` leaf has one value per agent (``[num_agents]``: ``terminated``,
  ``truncated``), so their ``info.reshape(NUM_ACTORS)`` and ``LogWrapper`` work; the final
  observation of an ended episode is not an info leaf: :meth:`SocialNavJaxMARL.step_env` returns
  it before the reset;
- a centralised critic's input is :meth:`SocialNavJaxMARL.world_state` (every robot's
  observation concatenated, ``world_state_size()`` long), which is what JaxMARL's MAPPO world-state
  wrappers compute from the observation dict.

Without sgjax's own auto-reset, the per-environment step counter that reward schedules read
(``state.total_steps``) is carried across JaxMARL's resets by :meth:`SocialNavJaxMARL.step`.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from jax import Array

from sgjax.environment.registry import make as make_env
from sgjax.environment.registry import registered
from sgjax.types import EnvParams, EnvState

EXTRA_HINT = ("sgjax.adapters.jaxmarl needs JaxMARL: pip install 'sgjax[jaxmarl]' "
              "(jaxmarl>=0.2 and the six module its gymnax dependency imports)")

try:
    from jaxmarl.environments.multi_agent_env import MultiAgentEnv
    from jaxmarl.environments.spaces import Box, Discrete
except ImportError as _err:  # the optional extra is not installed
    _IMPORT_ERROR: ImportError | None = _err

    class MultiAgentEnv:  # type: ignore[no-redef]
        """Stands in for JaxMARL's base class when JaxMARL is not installed."""

        def __init__(self, num_agents: int):
            raise ImportError(EXTRA_HINT) from _IMPORT_ERROR
else:
    _IMPORT_ERROR = None

ENV_PREFIX = "sgjax_"


class SocialNavJaxMARL(MultiAgentEnv):
    """A shipped scenario (or map file / ``MapSpec``) as a JaxMARL environment of
    ``num_agents`` robots; ``overrides`` are ``sgjax.make`` options (``action_mode``,
    ``num_humans``, ``time_limit``, ...)."""

    def __init__(self, scenario: Any = "doorway", num_agents: int = 4,
                 params: EnvParams | None = None, **overrides: Any):
        super().__init__(num_agents)
        if "max_agents" in overrides:
            raise TypeError("SocialNavJaxMARL: max_agents is num_agents here (JaxMARL agents are "
                            "fixed per environment)")
        self.env, default_params = make_env(scenario, num_agents=num_agents, **overrides)
        self.params = default_params if params is None else params
        self.agents = [f"robot_{i}" for i in range(num_agents)]
        size = self.env.observation_size
        observation = Box(-jnp.inf, jnp.inf, (size,), jnp.float32)
        act_space = self.env.action_space(self.params)
        self.discrete = hasattr(act_space, "n")
        action = (Discrete(int(act_space.n)) if self.discrete
                  else Box(-1.0, 1.0, tuple(act_space.shape), jnp.float32))
        self.action_dim = 1 if self.discrete else int(act_space.shape[0])
        self.observation_spaces = {a: observation for a in self.agents}
        self.action_spaces = {a: action for a in self.agents}

    @property
    def name(self) -> str:
        return f"{ENV_PREFIX}{self.env.config.scenario}"

    @property
    def agent_classes(self) -> dict[str, list[str]]:
        return {"robot": list(self.agents)}

    def _to_dict(self, stacked: Array) -> dict[str, Array]:
        return {a: stacked[i] for i, a in enumerate(self.agents)}

    def _stack_actions(self, actions: dict[str, Any]) -> Array:
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise KeyError(f"SocialNavJaxMARL.step: no action for {missing}")
        if self.discrete:
            return jnp.stack([jnp.reshape(jnp.asarray(actions[a]), ()) for a in self.agents])
        return jnp.stack([jnp.reshape(jnp.asarray(actions[a], jnp.float32), (self.action_dim,))
                          for a in self.agents])

    def reset(self, key: Array) -> tuple[dict[str, Array], EnvState]:
        obs, state = self.env.reset(key, self.params)
        return self._to_dict(obs), state

    def get_obs(self, state: EnvState) -> dict[str, Array]:
        return self._to_dict(self.env.observe(state, self.params))

    def step_env(self, key: Array, state: EnvState, actions: dict[str, Any]
                 ) -> tuple[dict, EnvState, dict, dict, dict]:
        """One step without auto-reset: the observations are those the step ended in (the final
        observation when the episode ended)."""
        obs, state, reward, terminated, truncated, info = self.env.step_env(
            key, state, self._stack_actions(actions), self.params)
        done = terminated | truncated
        dones = self._to_dict(done)
        dones["__all__"] = jnp.all(~state.robots.present | done)  # as sgjax's own step
        infos = {"terminated": terminated, "truncated": truncated}
        return self._to_dict(obs), state, self._to_dict(reward), dones, infos

    def step(self, key: Array, state: EnvState, actions: dict[str, Any],
             reset_state: EnvState | None = None) -> tuple[dict, EnvState, dict, dict, dict]:
        """JaxMARL's step: :meth:`step_env`, then a reset where the episode ended, to
        ``reset_state`` when given (else a fresh ``reset``)."""
        key, key_reset = jax.random.split(key)
        obs, after, rewards, dones, infos = self.step_env(key, state, actions)
        if reset_state is None:
            fresh_obs, fresh = self.reset(key_reset)
            fresh = fresh.replace(total_steps=after.total_steps)
        else:
            fresh, fresh_obs = reset_state, self.get_obs(reset_state)
        done = dones["__all__"]
        pick = lambda new, old: jax.lax.select(done, new, old)  # noqa: E731
        return (jax.tree.map(pick, fresh_obs, obs), jax.tree.map(pick, fresh, after), rewards,
                dones, infos)

    def get_avail_actions(self, state: EnvState) -> dict[str, Array]:
        """Every action is always available (``[n]`` bool; ``[d]`` for continuous actions)."""
        size = self.action_spaces[self.agents[0]].n if self.discrete else self.action_dim
        return {a: jnp.ones(size, bool) for a in self.agents}

    def world_state(self, obs: dict[str, Array]) -> Array:
        """Every robot's observation concatenated, ``[num_agents * D]``: a centralised critic's
        input (JaxMARL's MAPPO builds the same from the observation dict)."""
        return jnp.concatenate([obs[a] for a in self.agents])

    def world_state_size(self) -> int:
        return self.num_agents * self.env.observation_size


def registered_envs() -> list[str]:
    """The ids :func:`make` takes: ``sgjax_<scenario>`` for every shipped scenario."""
    return [f"{ENV_PREFIX}{name}" for name in registered()]


def make_jaxmarl(env_id: str, **kwargs: Any) -> SocialNavJaxMARL:
    """``jaxmarl.make``-style construction: ``make_jaxmarl("sgjax_doorway", num_agents=4, ...)``."""
    if _IMPORT_ERROR is not None:
        raise ImportError(EXTRA_HINT) from _IMPORT_ERROR
    if env_id not in registered_envs():
        raise ValueError(f"{env_id!r} is not an sgjax JaxMARL environment; registered: "
                         f"{', '.join(registered_envs())}")
    return SocialNavJaxMARL(env_id[len(ENV_PREFIX):], **kwargs)
