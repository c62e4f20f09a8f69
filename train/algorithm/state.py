"""The training state's leaf types: a lane's :class:`RunnerState`, one step's
:class:`Transition` and one update's :class:`Rollout` (``B = num_envs x slots`` agents)."""

from __future__ import annotations

from typing import Any

from flax import struct
from jax import Array

from train.algorithm.normalize import RunningStats


@struct.dataclass
class RunnerState:
    params: Any
    opt_state: Any
    obs_stats: RunningStats
    return_stats: RunningStats
    returns: Array  # [E, R] running discounted return (reward scaling)
    episode_return: Array  # [E, R] undiscounted return of the current episode (logging)
    env_states: tuple
    obs: Array  # [E, R, D] raw
    carry: tuple  # network memory, [B, H] each
    starts: Array  # [E, R] bool: the next step is an episode's first
    key: Array
    steps: Array  # int32: environment steps so far (whole batch)
    term_weights: dict  # {reward term: multiplier} on info["reward_terms"] (1: as configured)
    obs_mask: Array  # [D] multiplier on every observation (1: all features seen)
    # {LANE_SETTINGS name: float32, "gamma_lambda"}: this lane's algorithm numbers, which the
    # program reads for the settings its Trainer's ``varied`` names (LaneSettings.read)
    hyper: dict
    # a curriculum over generated worlds: a LevelBuffer per scenario (None where the trainer
    # does not pick worlds); () without one (train.algorithm.world_curriculum)
    levels: tuple = ()
    # this lane's curriculum numbers (LevelsConfig.lane_values: replay_prob, mutate_prob,
    # learnability; float32), so lanes may follow different methods; {} without a curriculum
    curriculum: dict = struct.field(default_factory=dict)


@struct.dataclass
class Transition:
    actor_in: Array  # [B, D]
    critic_in: Array | None  # [B, G] under MAPPO; None under IPPO, where it is actor_in
    starts: Array  # [B]
    action: Array  # [B] or [B, A]
    logp: Array
    value: Array
    reward: Array  # scaled
    terminated: Array
    truncated: Array
    final_value: Array  # critic's value of the final observation where truncated, else 0
    active: Array
    decides: Array  # the environment read this action (make's decision_period; else held)


@struct.dataclass
class Rollout:
    """One update's data for the learning phase (``T = num_steps`` steps, ``B`` agents)."""

    memory: tuple  # network memory at the rollout's first step, [B, H] each
    traj: Transition  # [T, B, ...]
    advantages: Array  # [T, B]
    targets: Array  # [T, B] value targets


def critic_input(traj: Transition) -> Array:
    """The critic's input of stored transitions (the actor's under IPPO, stored once)."""
    return traj.actor_in if traj.critic_in is None else traj.critic_in
