"""The rollout half of a PPO update as pure functions: ``num_steps`` steps of the whole
environment batch (actions sampled, rewards weighted, shared and scaled, truncated robots
bootstrapped), then GAE.

:class:`RolloutParts` holds what a step reads that is not state (the environment batch, the
network, the actor's layout, the settings); :func:`env_step` is one ``lax.scan`` step and
:func:`collect` the whole rollout. One environment step reads this module, the environment
batch (:mod:`train.algorithm.env_batch`) and the actor's inputs (:mod:`train.algorithm.actor`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
from jax import Array

from sgjax.evaluation.metrics import team_success
from sgjax.kernels.row_chunks import chunk_size, update_flagged_rows
from train.algorithm.actor import ActorLayout, agent_inputs, head_log_std
from train.algorithm.config import AlgorithmConfig, LevelsConfig, NetworkConfig
from train.algorithm.env_batch import EnvBatch, share_rewards
from train.algorithm.gae import gae
from train.algorithm.lane_settings import LaneSettings
from train.algorithm.networks import ActorCritic, log_prob, sample
from train.algorithm.normalize import RunningStats
from train.algorithm.state import Rollout, RunnerState, Transition
from train.algorithm.world_curriculum import choose_levels, played_levels, record_levels


@dataclasses.dataclass(frozen=True, eq=False)
class RolloutParts:
    """What the rollout reads besides the runner state."""

    batch: EnvBatch
    network: ActorCritic
    network_config: NetworkConfig
    layout: ActorLayout
    algorithm: AlgorithmConfig
    settings: LaneSettings
    mappo: bool
    stage_steps: Array  # [stages] int32: the curriculum's first environment step of each stage
    stage_counts: Array  # [stages] int32: its robot count
    levels: LevelsConfig = LevelsConfig()  # the curriculum over generated worlds

    @property
    def num_envs(self) -> int:
        return sum(self.batch.sizes)

    @property
    def slots(self) -> int:
        return self.batch.slots

    def num_agents_at(self, steps: Array) -> Array:
        """The curriculum's robot count after ``steps`` environment steps (int32 scalar)."""
        stage = jnp.sum(steps >= self.stage_steps) - 1
        return self.stage_counts[stage]

    def inputs(self, obs_stats: RunningStats, obs: Array) -> tuple[Array, Array]:
        """Actor and critic inputs ``[B, .]`` for a batch ``obs [E, R, D]``."""
        return agent_inputs(self.network_config, self.layout, self.mappo, obs_stats, obs)


def env_step(parts: RolloutParts, runner: RunnerState, _: Any = None
             ) -> tuple[RunnerState, tuple[Transition, dict]]:
    """One step of the whole batch: act, step every environment, weight, share and scale the
    rewards, bootstrap truncated robots; returns the advanced runner, the step's
    :class:`Transition` ``[B, ...]`` and its episode logs (sums over the episodes that ended)."""
    a, batch = parts.algorithm, parts.batch
    num_envs, slots = parts.num_envs, parts.slots
    key, k_act, k_env = jax.random.split(runner.key, 3)
    played = played_levels(batch, runner.env_states) if parts.levels.active else None
    active = batch.active_slots(runner.env_states)  # [E, R]
    obs_stats = runner.obs_stats
    if a.normalize_observations:
        obs_stats = obs_stats.update(runner.obs.reshape(-1, batch.obs_size), active.reshape(-1))
    actor_in, critic_in = parts.inputs(obs_stats, runner.obs)
    starts = runner.starts.reshape(-1)
    carry, out, value = parts.network.apply(runner.params, runner.carry, actor_in[None],
                                            critic_in[None], starts[None])
    out, value = out[0], value[0]
    log_std = head_log_std(runner.params, batch.discrete)
    action = sample(k_act, out, log_std, batch.discrete)
    logp = log_prob(out, log_std, action, batch.discrete)
    if batch.discrete:
        env_action = action.reshape(num_envs, slots)
    else:
        env_action = jnp.clip(action, -1.0, 1.0).reshape(num_envs, slots, -1)
    obs, states, _, term, trunc, info = batch.step(
        k_env, runner.env_states, env_action, parts.num_agents_at(runner.steps))
    obs = obs * runner.obs_mask
    reward = sum(runner.term_weights[name] * value
                 for name, value in info["reward_terms"].items())
    if "team_reward" in parts.settings.varied:  # a lane value (train.sweep)
        reward = share_rewards(reward, info["was_active"], runner.hyper["team_reward"])
    elif a.team_reward:
        reward = share_rewards(reward, info["was_active"], a.team_reward)

    done = term | trunc
    returns = runner.returns * parts.settings.read(runner.hyper, "gamma") + reward
    return_stats = runner.return_stats
    if a.normalize_rewards:
        return_stats = return_stats.update(returns.reshape(-1, 1), active.reshape(-1))
        scaled = return_stats.scale(reward, a.reward_clip)
    else:
        scaled = reward
    returns = jnp.where(done | ~active, 0.0, returns)

    final_value = final_values(parts, runner.params, carry, obs_stats,
                               info["final_observation"], runner.obs_mask, trunc)
    episode_done = info["episode_done"]
    transition = Transition(
        actor_in=actor_in, critic_in=critic_in if parts.mappo else None, starts=starts,
        action=action, logp=logp, value=value, reward=scaled.reshape(-1),
        terminated=term.reshape(-1), truncated=trunc.reshape(-1), final_value=final_value,
        active=active.reshape(-1),
        decides=jnp.broadcast_to(info["decided"][:, None], (num_envs, slots)).reshape(-1))

    episode_return = runner.episode_return + jnp.where(active, reward, 0.0)
    log = episode_logs(episode_done, info["final_present"], info["final_succeeded"],
                       episode_return)
    ended = None
    if played is not None:  # what a curriculum records of the episodes that ended
        present = info["final_present"]
        ended = {"done": episode_done, "played": played,
                 "success": (jnp.sum(present & info["final_succeeded"], axis=1)
                             / jnp.maximum(jnp.sum(present, axis=1), 1))}
    runner = runner.replace(
        obs_stats=obs_stats, return_stats=return_stats, returns=returns,
        episode_return=jnp.where(episode_done[:, None], 0.0, episode_return),
        env_states=states, obs=obs, carry=carry,
        starts=jnp.broadcast_to(episode_done[:, None], (num_envs, slots)),
        key=key, steps=runner.steps + num_envs)
    return runner, (transition, log, ended)


def episode_logs(episode_done: Array, present: Array, succeeded: Array,
                 episode_return: Array) -> dict[str, Array]:
    """Sums over the episodes that ended this step (``episode_done [E]``; ``present``,
    ``succeeded`` and ``episode_return [E, R]`` of their robots): episodes, team successes,
    robots, robot successes and the robots' returns."""
    team = team_success(present, succeeded)
    ended = episode_done.astype(jnp.float32)
    return {
        "episodes": jnp.sum(ended),
        "team_successes": jnp.sum(ended * team),
        "robots": jnp.sum(ended[:, None] * present),
        "robot_successes": jnp.sum(ended[:, None] * (present & succeeded)),
        "return_sum": jnp.sum(ended[:, None] * present * episode_return),
    }


def final_values(parts: RolloutParts, params: Any, carry: tuple, obs_stats: RunningStats,
                 final_obs: Array, obs_mask: Array, truncated: Array) -> Array:
    """The critic's values ``[B]`` of the final observations ``final_obs [E, R, D]`` (times
    ``obs_mask [D]``) of the environments with a truncated robot (``truncated [E, R]``), 0
    elsewhere (GAE reads a final value only where its robot was truncated).

    Few environments truncate in a step (a time limit, a stuck robot), so the critic runs on
    them alone, a chunk at a time (:func:`sgjax.kernels.row_chunks.update_flagged_rows`, none
    in most steps), instead of on every row of the batch every step. Whole environments,
    because MAPPO's critic reads every robot of one."""
    num_envs, slots = truncated.shape
    chunk = chunk_size(num_envs)
    critic_carry = jax.tree.map(lambda x: x.reshape((num_envs, slots) + x.shape[1:]), carry[1])

    def some(index: Array, values: Array) -> Array:
        rows = jnp.minimum(index, num_envs - 1)
        actor_in, critic_in = parts.inputs(obs_stats, final_obs[rows] * obs_mask)
        memory = jax.tree.map(
            lambda x: x[rows].reshape((chunk * slots,) + x.shape[2:]), critic_carry)
        _, value = parts.network.apply(
            params, memory, actor_in[None], critic_in[None],
            jnp.zeros((1, chunk * slots), bool), method=ActorCritic.value)
        return values.at[index].set(value[0].reshape(chunk, slots), mode="drop")

    values = update_flagged_rows(jnp.any(truncated, axis=1), chunk, some,
                                 jnp.zeros((num_envs, slots), jnp.float32))
    return values.reshape(-1)


def critic_value(parts: RolloutParts, params: Any, carry: tuple, actor_in: Array,
                 critic_in: Array, starts: Array) -> Array:
    """The critic's value ``[B]`` of one step's inputs (``actor_in [B, D]``, ``critic_in
    [B, G]``, ``starts [B]``) from the memory ``carry``, without the actor's forward pass."""
    _, value = parts.network.apply(params, carry[1], actor_in[None], critic_in[None],
                                   starts[None], method=ActorCritic.value)
    return value[0]


def collect(parts: RolloutParts, runner: RunnerState) -> tuple[RunnerState, Rollout, dict]:
    """``num_steps`` steps of the whole batch (:func:`env_step`), then GAE. Returns the
    advanced runner, the learning phase's data and the per-step logs ``[T]``.

    Under a curriculum over generated worlds (``parts.levels``), the levels of the next
    episodes are chosen before the steps and the episodes that ended are scored and recorded
    after GAE (:mod:`train.algorithm.world_curriculum`; its buffer statistics join the logs as
    scalars)."""
    batch, levels = parts.batch, parts.levels
    if levels.active:
        key, k_levels = jax.random.split(runner.key)
        buffers, states = choose_levels(batch, levels, k_levels, runner.levels,
                                        runner.env_states, runner.steps, runner.curriculum)
        runner = runner.replace(key=key, levels=buffers, env_states=states)
    memory = runner.carry
    runner, (traj, logs, ended) = jax.lax.scan(lambda r, x: env_step(parts, r, x), runner,
                                               None, parts.algorithm.num_steps)
    actor_in, critic_in = parts.inputs(runner.obs_stats, runner.obs)
    last_value = critic_value(parts, runner.params, runner.carry, actor_in, critic_in,
                              runner.starts.reshape(-1))
    settings, hyper = parts.settings, runner.hyper
    advantages, targets = gae(traj, last_value, settings.read(hyper, "gamma"),
                              settings.read(hyper, "gamma_lambda"))
    if levels.active:
        buffers, stats = record_levels(batch, runner.levels, runner.steps, advantages,
                                       traj.active, ended, runner.curriculum)
        runner = runner.replace(levels=buffers)
        logs = {**logs, **stats}  # scalars: an update's sum of them is themselves
    return runner, Rollout(memory, traj, advantages, targets), logs
