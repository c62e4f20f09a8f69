"""The environment batch of a training run: several scenarios, each on a fixed share of the
environments, stepped as one batch ``[E, R, ...]`` (``E`` environments, ``R`` robot slots);
reward sharing within a team; the observation mask of hidden features."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from sgjax.environment.env import SocialNavEnv
from sgjax.environment.registry import make
from sgjax.maps.generated.families import PREFIX as GENERATED
from sgjax.terms.base import ConfigError
from train.algorithm.config import TrainConfig


class EnvBatch:
    """Several scenarios trained at once, each on a fixed share of the environment batch (so
    every update sees all of them; an environment keeps its scenario across episodes)."""

    def __init__(self, config: TrainConfig):
        e = config.env
        count = len(e.scenarios)
        if config.algorithm.num_envs < count:
            raise ConfigError(f"algorithm.num_envs ({config.algorithm.num_envs}) must be at "
                              f"least the number of scenarios ({count})")
        base, extra = divmod(config.algorithm.num_envs, count)
        self.sizes = tuple(base + (i < extra) for i in range(count))
        # Under a curriculum of worlds the trainer picks each generated world (levels).
        picked = [config.levels.active and s.startswith(GENERATED) for s in e.scenarios]
        if config.levels.active and not any(picked):
            raise ConfigError(f"levels.method {config.levels.method!r} picks generated worlds, "
                              f"but env.scenarios {list(e.scenarios)} has none "
                              f"({GENERATED}<family>)")
        pairs = [make(s, options=e.options.replace(world_levels=True) if pick else e.options,
                      num_agents=e.curriculum[0][1], max_agents=e.slots)
                 for s, pick in zip(e.scenarios, picked, strict=True)]
        self.envs = tuple(env for env, _ in pairs)
        self.params = tuple(params for _, params in pairs)
        # each scenario's world source when the trainer picks its worlds, else None
        self.level_sources = tuple(env.config.world if pick else None
                                   for env, pick in zip(self.envs, picked, strict=True))
        first = self.envs[0]
        for scenario, env in zip(e.scenarios, self.envs, strict=True):
            if env.observation_size != first.observation_size:
                raise ConfigError(f"env.scenarios: {scenario!r} has observations of size "
                                  f"{env.observation_size}, {e.scenarios[0]!r} of "
                                  f"{first.observation_size}; use the same terms and zones")
        self.slots = e.slots
        self.obs_size = first.observation_size
        self.discrete = first.config.action_mode == "go_stop"
        self.action_dim = 2 if self.discrete else first.config.action_dim

    @property
    def env(self) -> SocialNavEnv:
        return self.envs[0]

    def _params(self, num_agents: Array) -> tuple:
        return tuple(p.replace(num_agents=num_agents) for p in self.params)

    def split(self, x: Array, axis: int = 0) -> list[Array]:
        """``x`` cut along ``axis`` (its ``E`` environments) into the scenarios' shares
        (``E_s`` each)."""
        out, start = [], 0
        for size in self.sizes:
            out.append(jax.lax.slice_in_dim(x, start, start + size, axis=axis))
            start += size
        return out

    def reset(self, key: Array, num_agents: Array) -> tuple[Array, tuple]:
        keys = self.split(jax.random.split(key, sum(self.sizes)))
        obs, states = [], []
        for env, params, k in zip(self.envs, self._params(num_agents), keys, strict=True):
            o, s = jax.vmap(env.reset, in_axes=(0, None))(k, params)
            obs.append(o)
            states.append(s)
        return jnp.concatenate(obs), tuple(states)

    def step(self, key: Array, states: tuple, actions: Array, num_agents: Array
             ) -> tuple[Array, tuple, Array, Array, Array, dict]:
        keys = self.split(jax.random.split(key, sum(self.sizes)))
        parts = []
        for env, params, k, s, a in zip(self.envs, self._params(num_agents), keys, states,
                                        self.split(actions), strict=True):
            obs, state, reward, term, trunc, info = env.step_batch(k, s, a, params)
            final = info["final_robots"]
            parts.append((obs, state, reward, term, trunc, {
                "was_active": info["was_active"], "episode_done": info["episode_done"],
                "decided": info["decided"],
                "reward_terms": info["reward_terms"],
                "final_observation": info["final_observation"],
                "final_present": final.present, "final_succeeded": final.succeeded}))
        cat = lambda *xs: jnp.concatenate(xs)  # noqa: E731
        obs, _, reward, term, trunc, info = jax.tree.map(
            cat, *[(p[0], None, p[2], p[3], p[4], p[5]) for p in parts])
        return obs, tuple(p[1] for p in parts), reward, term, trunc, info

    def active_slots(self, states: tuple) -> Array:
        return jnp.concatenate([s.robots.active for s in states])

    def reward_term_names(self) -> tuple[str, ...]:
        """Names in ``info["reward_terms"]`` (reward terms, and enders that pay, e.g. stuck)."""
        return self._reward_terms

    @functools.cached_property
    def _reward_terms(self) -> tuple[str, ...]:
        """:meth:`reward_term_names`, read from the step's traced output once per batch."""
        env, params = self.env, self.params[0]
        key = jax.random.PRNGKey(0)
        _, state = jax.eval_shape(env.reset, key, params)
        action = (jnp.zeros(env.max_agents, jnp.int32) if self.discrete
                  else jnp.zeros((env.max_agents, self.action_dim)))
        info = jax.eval_shape(env.step_env, key, state, action, params)[-1]
        return tuple(info["reward_terms"])


def share_rewards(reward: Array, acted: Array, share: float) -> Array:
    """Each robot's reward ``[E, R]`` mixed with its team's: ``(1 - share) x own + share x
    the mean over the robots of its environment that acted this step`` (``acted [E, R]``);
    robots that did not act get 0."""
    team = (jnp.sum(jnp.where(acted, reward, 0.0), axis=1, keepdims=True)
            / jnp.maximum(jnp.sum(acted, axis=1, keepdims=True), 1))
    return jnp.where(acted, (1.0 - share) * reward + share * team, 0.0)


def observation_mask(env: Any, hide: Sequence[str]) -> np.ndarray:
    """``[D]`` ones, with zeros on the hidden columns of ``env``'s observation, found in its
    column layout (``env.config.observer.columns``)."""
    mask = np.ones(env.observation_size, np.float32)
    columns = env.config.observer.columns(env.config.layout)
    for item in hide:
        term, _, feature = item.partition(".")
        if term not in columns:
            raise ConfigError(f"hide {item!r}: no observation term {term!r}; this "
                              f"observation has {list(columns.slices)}")
        try:
            mask[columns.indices(item)] = 0.0
        except ValueError:
            raise ConfigError(
                f"hide {item!r}: {term!r} has no feature {feature!r}; its features are "
                f"{', '.join(columns[term].feature_names)} (hide a term, or <term>.<feature>)"
            ) from None
    return mask
