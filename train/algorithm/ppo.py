"""IPPO and MAPPO with parameter sharing, as jitted functions (the purejaxrl shape).

Every robot slot of every environment is one agent of a shared network; agents are laid out
``B = num_envs x slots``. One update collects ``num_steps`` steps of the whole batch with
``lax.scan`` (auto-reset inside the environment), computes GAE, and runs ``update_epochs``
passes of ``num_minibatches`` minibatches over agent sequences. Robots that are absent or have
finished (``info["was_active"]`` false) are masked out of every loss and statistic.

* IPPO: actor and critic read the robot's own observation (plus a one-hot id with
  ``network.agent_id``). MAPPO: the critic reads the global state, every robot's observation of
  its environment concatenated, plus the robot's one-hot id.
* Truncated robots (time limit, stuck ender) are bootstrapped with the critic's value of
  ``info["final_observation"]``; terminated ones are not.
* Observations are normalised by running statistics of the acting robots' observations, rewards
  scaled by the running spread of each robot's discounted return (SB3 ``VecNormalize``).

``Trainer(config).train(key)`` is a whole run in one jitted function; ``train_lanes(keys)`` runs
several seeds as lanes of one function (``algorithm.lanes``: one ``vmap``, or the rollouts
batched and the learning phases one lane after another, faster on a CPU). ``init`` +
``update_chunk`` (``update_chunk_lanes``) give the same run in pieces for the command line's
progress bar, evaluation and checkpoints.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import struct
from jax import Array

from sgjax.compilation_cache import learner_compiler_options
from sgjax.environment.env import SocialNavEnv
from sgjax.environment.registry import make
from sgjax.evaluation.metrics import team_success
from sgjax.evaluation.policies import RecurrentPolicy
from sgjax.kernels.row_chunks import chunk_size, update_flagged_rows
from sgjax.terms.base import ConfigError
from train.algorithm.actor import (
    ActorLayout,
    ActorWeights,
    acting_policy,
    actor_features,
    head_log_std,
)
from train.algorithm.config import TrainConfig, resolved_compact, resolved_lanes
from train.algorithm.networks import (
    ActorCritic,
    entropy,
    initial_carry,
    log_prob,
    most_seen,
    others_layout,
    sample,
)
from train.algorithm.normalize import RunningStats

LOSS_TERMS = ("policy_loss", "value_loss", "entropy", "approx_kl")  # learn's aux, per minibatch
# algorithm.compact: a minibatch's units are computed in whole chunks of 1/COMPACT_CHUNKS of it,
# then the rest in half chunks (the last one partly padded with units that cannot learn), each
# chunk gathering its own units' data: eight chunks keep each chunk's products large while the
# padding stays under a sixteenth of a minibatch (the variants' timings: docs/notes/
# benchmark-journal.md, session 29; bench/learner_roofline.py measures it).
COMPACT_CHUNKS = 8
# Algorithm settings held as numbers in the runner state (``RunnerState.hyper``), which the
# compiled program reads there when its Trainer is told that lanes vary them (``varied``), so
# that the lanes of one call may differ in them: ``train.sweep`` trains trials that differ only
# in these (and in reward-term weights and observation masks) side by side. Every other
# setting is part of the program.
LANE_SETTINGS = ("learning_rate", "ent_coef", "vf_coef", "clip_eps", "gamma", "gae_lambda",
                 "team_reward")


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
        pairs = [make(s, options=e.options, num_agents=e.curriculum[0][1],
                      max_agents=e.slots) for s in e.scenarios]
        self.envs = tuple(env for env, _ in pairs)
        self.params = tuple(params for _, params in pairs)
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

    def _split(self, x: Array) -> list[Array]:
        out, start = [], 0
        for size in self.sizes:
            out.append(x[start:start + size])
            start += size
        return out

    def reset(self, key: Array, num_agents: Array) -> tuple[Array, tuple]:
        keys = self._split(jax.random.split(key, sum(self.sizes)))
        obs, states = [], []
        for env, params, k in zip(self.envs, self._params(num_agents), keys, strict=True):
            o, s = jax.vmap(env.reset, in_axes=(0, None))(k, params)
            obs.append(o)
            states.append(s)
        return jnp.concatenate(obs), tuple(states)

    def step(self, key: Array, states: tuple, actions: Array, num_agents: Array
             ) -> tuple[Array, tuple, Array, Array, Array, dict]:
        keys = self._split(jax.random.split(key, sum(self.sizes)))
        parts = []
        for env, params, k, s, a in zip(self.envs, self._params(num_agents), keys, states,
                                        self._split(actions), strict=True):
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
    # program reads for the settings its Trainer's ``varied`` names (Trainer.setting)
    hyper: dict


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


class Trainer:
    """Builds the environment batch, the network and the optimiser from a ``TrainConfig``."""

    def __init__(self, config: TrainConfig, varied: Sequence[str] = ()):
        """``varied``: the :data:`LANE_SETTINGS` that lanes of one call may set differently
        from ``config`` (``train.sweep`` names them): the program reads those from each
        lane's runner state (``RunnerState.hyper``) and the others as constants of the
        config (:meth:`setting`), so a run that varies nothing is the program it always was.
        With ``team_reward`` among them every lane mixes its rewards (by its own share, 0
        included); else only a config with a share above 0 does."""
        unknown = sorted(set(varied) - set(LANE_SETTINGS))
        if unknown:
            raise ConfigError(f"Trainer(varied=...): {unknown} are not lane settings "
                              f"{list(LANE_SETTINGS)}")
        self.varied = frozenset(varied)
        self.config = config
        self._jitted_chunks: dict[tuple[int, bool], Any] = {}  # jitted_chunk_lanes' jits
        a = config.algorithm
        self.batch = EnvBatch(config)
        self.num_envs = sum(self.batch.sizes)
        self.slots = self.batch.slots
        self.num_agents = self.num_envs * self.slots
        if self.num_agents % a.num_minibatches:
            raise ConfigError(f"algorithm.num_minibatches ({a.num_minibatches}) must divide "
                              f"num_envs x robot slots ({self.num_agents})")
        self.mappo = a.name == "mappo"
        self.sequential_lanes = resolved_lanes(a.lanes, jax.default_backend()) == "sequential"
        self.compact = resolved_compact(a.compact, jax.default_backend())
        self.actor = ActorLayout(
            obs_size=self.batch.obs_size, slots=self.slots, discrete=self.batch.discrete,
            action_dim=self.batch.action_dim, normalize=a.normalize_observations,
            others=others_layout(self.batch.env))
        # Trained only in these environments: the others encoder skips the slots that are
        # always empty there (the saved layout keeps every slot for other robot counts).
        seen = [most_seen(env) for env in self.batch.envs]
        self.network = ActorCritic(config.network, self.actor.action_dim, self.actor.discrete,
                                   self.actor.others, centralised=self.mappo,
                                   bodies=None if None in seen else max(seen))
        updates = a.num_updates * a.update_epochs * a.num_minibatches
        lr = (optax.linear_schedule(a.learning_rate, 0.0, updates) if a.anneal_lr
              else a.learning_rate)
        self.optimizer = optax.chain(optax.clip_by_global_norm(a.max_grad_norm),
                                     optax.adam(lr, eps=1e-5))
        stages = config.env.curriculum
        self._stage_steps = jnp.asarray([s for s, _ in stages], jnp.int32)
        self._stage_counts = jnp.asarray([n for _, n in stages], jnp.int32)
        self._fresh_run = jax.jit(self._start)

    # ------------------------------------------------------------------ inputs
    def num_agents_at(self, steps: Array) -> Array:
        stage = jnp.sum(steps >= self._stage_steps) - 1
        return self._stage_counts[stage]

    def actor_input(self, obs_stats: RunningStats, obs: Array) -> Array:
        """``obs [..., R, D]`` -> normalised actor input ``[..., R, D (+ R)]``."""
        return actor_features(self.config.network, self.actor, obs_stats, obs)

    def inputs(self, obs_stats: RunningStats, obs: Array) -> tuple[Array, Array]:
        """Actor and critic inputs ``[B, .]`` for a batch ``obs [E, R, D]``."""
        actor = self.actor_input(obs_stats, obs)
        if self.mappo:
            x = (obs_stats.normalize(obs) if self.config.algorithm.normalize_observations
                 else obs)
            joint = x.reshape(x.shape[0], 1, -1)
            ids = jnp.broadcast_to(jnp.eye(self.slots), x.shape[:-1] + (self.slots,))
            critic = jnp.concatenate(
                [jnp.broadcast_to(joint, x.shape[:-1] + joint.shape[-1:]), ids], axis=-1)
        else:
            critic = actor
        flat = lambda v: v.reshape((-1, v.shape[-1]))  # noqa: E731
        return flat(actor), flat(critic)

    # ------------------------------------------------------------------ init
    def setting(self, hyper: dict | None, name: str) -> Any:
        """A lane setting (:data:`LANE_SETTINGS`, or ``gamma_lambda``) as the program reads it:
        the lane's number from ``hyper`` (runner state) where lanes vary it (``varied``), else
        the config's value as a constant of the program (as before lane settings existed, so
        that a run that varies nothing compiles, and rounds, as it always did)."""
        a = self.config.algorithm
        lane = (self.varied & {"gamma", "gae_lambda"} if name == "gamma_lambda"
                else name in self.varied)
        if hyper is not None and lane:
            return hyper[name]
        return a.gamma * a.gae_lambda if name == "gamma_lambda" else getattr(a, name)

    def default_hyper(self) -> dict[str, Array]:
        """The configured values of :data:`LANE_SETTINGS` (``algorithm`` section), float32,
        and ``gamma_lambda``, GAE's ``gamma x gae_lambda`` (rounded to float32 once, from the
        float64 product: as a product of two Python numbers was before the settings became
        lane values)."""
        a = self.config.algorithm
        hyper = {name: jnp.float32(getattr(a, name)) for name in LANE_SETTINGS}
        hyper["gamma_lambda"] = jnp.float32(a.gamma * a.gae_lambda)
        return hyper

    def term_weights(self) -> dict[str, Array]:
        """Every reward term's multiplier as configured (``algorithm.term_weights``; 1 for a
        term it does not name), float32."""
        names = self.batch.reward_term_names()
        configured = self.config.algorithm.term_weights
        for name in configured:
            if name not in names:
                raise ConfigError(f"algorithm.term_weights: unknown reward term {name!r}; this "
                                  f"configuration pays {list(names)}")
        return {name: jnp.float32(configured.get(name, 1.0)) for name in names}

    def observation_mask(self) -> np.ndarray:
        """``[D]``: zeros on the features ``algorithm.hide`` names, ones elsewhere."""
        try:
            return observation_mask(self.batch.env, self.config.algorithm.hide)
        except ConfigError as err:
            raise ConfigError(f"algorithm.hide: {err}") from None

    def init(self, key: Array, term_weights: dict | None = None, obs_mask: Array | None = None,
             hyper: dict | None = None) -> RunnerState:
        """A fresh run. ``term_weights`` ({reward term: multiplier}, default the config's),
        ``obs_mask`` (``[D]``, default :meth:`observation_mask`) and ``hyper``
        ({:data:`LANE_SETTINGS` name: value}, default the config's) are arrays in the state,
        so a ``vmap`` over them trains reward and observation ablations
        (``notebooks/ablation.ipynb``) and hyper-parameter trials (``train.sweep``) at once
        (the program reads ``hyper`` for the settings its ``varied`` names)."""
        weights = self.term_weights()
        for name, value in (term_weights or {}).items():
            if name not in weights:
                raise ConfigError(f"term_weights: unknown reward term {name!r}; this "
                                  f"configuration pays {list(weights)}")
            weights[name] = jnp.asarray(value, jnp.float32)
        mask = jnp.asarray(self.observation_mask() if obs_mask is None else obs_mask)
        settings = self.default_hyper()
        for name, value in (hyper or {}).items():
            if name not in settings:
                raise ConfigError(f"hyper: {name!r} is not a lane setting; lanes may differ "
                                  f"in {list(LANE_SETTINGS)}")
            settings[name] = jnp.asarray(value, jnp.float32)
        if {"gamma", "gae_lambda"} & set(hyper or {}) and "gamma_lambda" not in hyper:
            settings["gamma_lambda"] = settings["gamma"] * settings["gae_lambda"]
        return self._fresh_run(key, weights, mask, settings)

    def lane_hyper(self, values: dict[str, float]) -> dict[str, np.ndarray]:
        """A lane's ``hyper`` for :meth:`init` (float32 numpy): the configured settings with
        ``values`` ({:data:`LANE_SETTINGS` name: value}) on top, and their ``gamma_lambda``
        rounded once from the float64 product, as :meth:`default_hyper` does (so a lane with
        the configured values trains exactly as the config alone)."""
        a = self.config.algorithm
        merged = {name: float(getattr(a, name)) for name in LANE_SETTINGS}
        for name, value in values.items():
            if name not in merged:
                raise ConfigError(f"hyper: {name!r} is not a lane setting; lanes may differ "
                                  f"in {list(LANE_SETTINGS)}")
            if name not in self.varied and float(value) != merged[name]:
                raise ConfigError(f"hyper: {name} = {value} differs from the config's "
                                  f"{merged[name]}, but this Trainer reads {name} from the "
                                  f"config: build it with Trainer(config, varied=[{name!r}])")
            merged[name] = float(value)
        out = {name: np.float32(value) for name, value in merged.items()}
        out["gamma_lambda"] = np.float32(merged["gamma"] * merged["gae_lambda"])
        return out

    def _start(self, key: Array, weights: dict, mask: Array, hyper: dict) -> RunnerState:
        """``init``'s body, compiled (``_fresh_run``): called eagerly, the network and
        environment initialisation ran op by op (seconds per call on a CPU)."""
        k_net, k_env, k_run = jax.random.split(key, 3)
        steps = jnp.zeros((), jnp.int32)
        obs, states = self.batch.reset(k_env, self.num_agents_at(steps))
        obs = obs * mask
        obs_stats = RunningStats.start(self.batch.obs_size)
        actor, critic = self.inputs(obs_stats, obs)
        carry = initial_carry(self.config.network, self.num_agents)
        starts = jnp.ones((self.num_envs, self.slots), bool)
        params = self.network.init(k_net, carry, actor[None], critic[None],
                                   starts.reshape(1, -1))
        zeros = jnp.zeros((self.num_envs, self.slots))
        return RunnerState(
            params=params, opt_state=self.optimizer.init(params), obs_stats=obs_stats,
            return_stats=RunningStats.start(1), returns=zeros, episode_return=zeros,
            env_states=states, obs=obs, carry=carry, starts=starts, key=k_run, steps=steps,
            term_weights=weights, obs_mask=mask, hyper=hyper)

    # ------------------------------------------------------------------ rollout
    def _log_std(self, params: Any) -> Array | None:
        return head_log_std(params, self.batch.discrete)

    def _env_step(self, runner: RunnerState, _: Any) -> tuple[RunnerState, tuple]:
        a = self.config.algorithm
        key, k_act, k_env = jax.random.split(runner.key, 3)
        active = self.batch.active_slots(runner.env_states)  # [E, R]
        obs_stats = runner.obs_stats
        if a.normalize_observations:
            obs_stats = obs_stats.update(runner.obs.reshape(-1, self.batch.obs_size),
                                         active.reshape(-1))
        actor_in, critic_in = self.inputs(obs_stats, runner.obs)
        starts = runner.starts.reshape(-1)
        carry, out, value = self.network.apply(runner.params, runner.carry, actor_in[None],
                                               critic_in[None], starts[None])
        out, value = out[0], value[0]
        log_std = self._log_std(runner.params)
        action = sample(k_act, out, log_std, self.batch.discrete)
        logp = log_prob(out, log_std, action, self.batch.discrete)
        if self.batch.discrete:
            env_action = action.reshape(self.num_envs, self.slots)
        else:
            env_action = jnp.clip(action, -1.0, 1.0).reshape(self.num_envs, self.slots, -1)
        num_agents = self.num_agents_at(runner.steps)
        obs, states, _, term, trunc, info = self.batch.step(
            k_env, runner.env_states, env_action, num_agents)
        obs = obs * runner.obs_mask
        reward = sum(runner.term_weights[name] * value
                     for name, value in info["reward_terms"].items())
        if "team_reward" in self.varied:  # a lane value (train.sweep)
            reward = share_rewards(reward, info["was_active"], runner.hyper["team_reward"])
        elif a.team_reward:
            reward = share_rewards(reward, info["was_active"], a.team_reward)

        done = term | trunc
        returns = runner.returns * self.setting(runner.hyper, "gamma") + reward
        return_stats = runner.return_stats
        if a.normalize_rewards:
            return_stats = return_stats.update(returns.reshape(-1, 1), active.reshape(-1))
            scaled = return_stats.scale(reward, a.reward_clip)
        else:
            scaled = reward
        returns = jnp.where(done | ~active, 0.0, returns)

        final_value = self._final_values(runner.params, carry, obs_stats,
                                         info["final_observation"], runner.obs_mask, trunc)
        episode_done = info["episode_done"]
        transition = Transition(
            actor_in=actor_in, critic_in=critic_in if self.mappo else None, starts=starts,
            action=action, logp=logp, value=value, reward=scaled.reshape(-1),
            terminated=term.reshape(-1), truncated=trunc.reshape(-1), final_value=final_value,
            active=active.reshape(-1),
            decides=jnp.broadcast_to(info["decided"][:, None],
                                     (self.num_envs, self.slots)).reshape(-1))

        episode_return = runner.episode_return + jnp.where(active, reward, 0.0)
        present, succeeded = info["final_present"], info["final_succeeded"]
        team = team_success(present, succeeded)
        ended = episode_done.astype(jnp.float32)
        log = {
            "episodes": jnp.sum(ended),
            "team_successes": jnp.sum(ended * team),
            "robots": jnp.sum(ended[:, None] * present),
            "robot_successes": jnp.sum(ended[:, None] * (present & succeeded)),
            "return_sum": jnp.sum(ended[:, None] * present * episode_return),
        }
        runner = runner.replace(
            obs_stats=obs_stats, return_stats=return_stats, returns=returns,
            episode_return=jnp.where(episode_done[:, None], 0.0, episode_return),
            env_states=states, obs=obs, carry=carry,
            starts=jnp.broadcast_to(episode_done[:, None], (self.num_envs, self.slots)),
            key=key, steps=runner.steps + self.num_envs)
        return runner, (transition, log)

    def _final_values(self, params: Any, carry: tuple, obs_stats: RunningStats,
                      final_obs: Array, obs_mask: Array, truncated: Array) -> Array:
        """The critic's values ``[B]`` of the final observations ``final_obs [E, R, D]``
        (times ``obs_mask [D]``) of the environments with a truncated robot (``truncated [E,
        R]``), 0 elsewhere (GAE reads a final value only where its robot was truncated).

        Few environments truncate in a step (a time limit, a stuck robot), so the critic runs
        on them alone, a chunk at a time (:func:`sgjax.kernels.row_chunks.update_flagged_rows`,
        none in most steps), instead of on every row of the batch every step. Whole
        environments, because MAPPO's critic reads every robot of one."""
        num_envs, slots = truncated.shape
        chunk = chunk_size(num_envs)
        critic_carry = jax.tree.map(
            lambda x: x.reshape((num_envs, slots) + x.shape[1:]), carry[1])

        def some(index: Array, values: Array) -> Array:
            rows = jnp.minimum(index, num_envs - 1)
            actor_in, critic_in = self.inputs(obs_stats, final_obs[rows] * obs_mask)
            memory = jax.tree.map(
                lambda x: x[rows].reshape((chunk * slots,) + x.shape[2:]), critic_carry)
            _, value = self.network.apply(
                params, memory, actor_in[None], critic_in[None],
                jnp.zeros((1, chunk * slots), bool), method=ActorCritic.value)
            return values.at[index].set(value[0].reshape(chunk, slots), mode="drop")

        values = update_flagged_rows(jnp.any(truncated, axis=1), chunk, some,
                                     jnp.zeros((num_envs, slots), jnp.float32))
        return values.reshape(-1)

    def _value(self, params: Any, carry: tuple, actor_in: Array, critic_in: Array,
               starts: Array) -> Array:
        """The critic's value ``[B]`` of one step's inputs (``actor_in [B, D]``, ``critic_in
        [B, G]``, ``starts [B]``) from the memory ``carry``, without the actor's forward pass
        (its output was thrown away here: the bootstrap values of truncated robots and of the
        rollout's last step)."""
        _, value = self.network.apply(params, carry[1], actor_in[None], critic_in[None],
                                      starts[None], method=ActorCritic.value)
        return value[0]

    def _advantages(self, traj: Transition, last_value: Array, hyper: dict | None = None
                    ) -> tuple[Array, Array]:
        gamma = self.setting(hyper, "gamma")
        gamma_lambda = self.setting(hyper, "gamma_lambda")

        def back(carry, t):
            advantage, next_value = carry
            bootstrap = jnp.where(t.truncated, t.final_value, next_value)
            delta = t.reward + gamma * bootstrap * (1.0 - t.terminated) - t.value
            done = (t.terminated | t.truncated).astype(jnp.float32)
            advantage = delta + gamma_lambda * (1.0 - done) * advantage
            return (advantage, t.value), advantage

        _, advantages = jax.lax.scan(back, (jnp.zeros_like(last_value), last_value), traj,
                                     reverse=True)
        return advantages, advantages + traj.value

    def _loss(self, params: Any, carry: tuple, traj: Transition, advantages: Array,
              targets: Array, hyper: dict | None = None) -> tuple[Array, dict]:
        def masked_mean(mask: Array) -> Any:
            mask = mask.astype(jnp.float32)
            count = jnp.maximum(jnp.sum(mask), 1.0)
            return lambda x: jnp.sum(x * mask) / count

        # The critic learns every active step; the actor only the steps whose action the
        # environment read (all of them unless make's decision_period holds actions).
        mean = masked_mean(traj.active)
        acted = masked_mean(traj.active & traj.decides)
        adv_mean = acted(advantages)
        adv_std = jnp.sqrt(acted(jnp.square(advantages - adv_mean)))
        adv = (advantages - adv_mean) / (adv_std + 1e-8)
        return self._loss_terms(params, carry, traj, adv, targets, mean, acted, hyper)

    def _loss_terms(self, params: Any, carry: tuple, traj: Transition, adv: Array,
                    targets: Array, mean: Callable[[Array], Array],
                    acted: Callable[[Array], Array], hyper: dict | None = None
                    ) -> tuple[Array, dict]:
        """The PPO loss of ``traj`` and its terms, with normalised advantages ``adv``:
        ``mean`` averages (or, for a chunk, sums into a share of) the critic's terms over
        the active steps, ``acted`` the actor's over the steps whose action was read
        (``hyper``: the lane's clip range and coefficients, default the config's)."""
        clip_eps = self.setting(hyper, "clip_eps")
        _, out, value = self.network.apply(params, carry, traj.actor_in, _critic_in(traj),
                                           traj.starts)
        log_std = self._log_std(params)
        logp = log_prob(out, log_std, traj.action, self.batch.discrete)
        ratio = jnp.exp(logp - traj.logp)
        policy_loss = -acted(jnp.minimum(ratio * adv, jnp.clip(ratio, 1.0 - clip_eps,
                                                               1.0 + clip_eps) * adv))
        clipped = traj.value + jnp.clip(value - traj.value, -clip_eps, clip_eps)
        value_loss = 0.5 * mean(jnp.maximum(jnp.square(value - targets),
                                            jnp.square(clipped - targets)))
        ent = acted(entropy(out, log_std, self.batch.discrete))
        total = (policy_loss + self.setting(hyper, "vf_coef") * value_loss
                 - self.setting(hyper, "ent_coef") * ent)
        approx_kl = acted((ratio - 1.0) - jnp.log(ratio))
        return total, {"policy_loss": policy_loss, "value_loss": value_loss, "entropy": ent,
                       "approx_kl": approx_kl}

    def collect(self, runner: RunnerState) -> tuple[RunnerState, Rollout, dict]:
        """The rollout half of an update: ``num_steps`` steps of the whole batch, then GAE.
        Returns the advanced runner, the learning phase's data and the per-step logs."""
        a = self.config.algorithm
        memory = runner.carry
        runner, (traj, logs) = jax.lax.scan(self._env_step, runner, None, a.num_steps)
        actor_in, critic_in = self.inputs(runner.obs_stats, runner.obs)
        last_value = self._value(runner.params, runner.carry, actor_in, critic_in,
                                 runner.starts.reshape(-1))
        advantages, targets = self._advantages(traj, last_value, runner.hyper)
        return runner, Rollout(memory, traj, advantages, targets), logs

    def learn(self, params: Any, opt_state: Any, key: Array, rollout: Rollout,
              hyper: dict | None = None) -> tuple[Any, Any, Array, dict]:
        """The learning half of an update: ``update_epochs`` passes of ``num_minibatches``
        minibatches of agent sequences. Returns the new parameters, optimiser state and key,
        and the loss terms ``[epochs, minibatches]``. ``hyper``: the lane's
        :data:`LANE_SETTINGS` (default the config's).

        Each epoch shuffles the agents once and cuts ``num_minibatches`` minibatches of
        ``num_agents / num_minibatches`` agents x ``num_steps`` steps. ``algorithm.compact``
        computes only each minibatch's active transitions (:meth:`_compact_step`); else every
        transition is computed and the inactive ones masked out (:meth:`_masked_step`). The
        minibatches and the optimiser steps are the same either way."""
        a = self.config.algorithm
        hyper = self.default_hyper() if hyper is None else hyper
        if self.compact:
            step = lambda carry, batch: self._compact_step(  # noqa: E731
                carry, batch, rollout, hyper)
        else:
            step = lambda carry, batch: self._masked_step(carry, batch, hyper)  # noqa: E731
        cut = self._compact_batches if self.compact else self._masked_batches

        def epoch(carry, key):
            order = jax.random.permutation(key, self.num_agents)
            return jax.lax.scan(step, carry, cut(order, rollout))

        key, k_epochs = jax.random.split(key)
        (params, opt_state), aux = jax.lax.scan(
            epoch, (params, opt_state), jax.random.split(k_epochs, a.update_epochs))
        return params, opt_state, key, aux

    # ------------------------------------------------------------------ learning, masked
    def _masked_batches(self, order: Array, rollout: Rollout) -> tuple:
        """Every minibatch of one epoch: the agents in ``order [B]`` (one gather), cut into
        ``M`` contiguous minibatches of ``U = B / M`` agents: ``(memory [M, U, H], traj
        [M, T, U, ...], advantages [M, T, U], targets [M, T, U])``."""
        minibatches = self.config.algorithm.num_minibatches
        size = self.num_agents // minibatches
        memory = jax.tree.map(lambda c: jnp.take(c, order, axis=0), rollout.memory)
        data = jax.tree.map(lambda x: jnp.take(x, order, axis=1),
                            (rollout.traj, rollout.advantages, rollout.targets))

        def cut_time_major(x):  # [T, B, ...] -> [M, T, B / M, ...]
            x = x.reshape((x.shape[0], minibatches, size) + x.shape[2:])
            return jnp.swapaxes(x, 0, 1)

        memory = jax.tree.map(
            lambda c: c.reshape((minibatches, size) + c.shape[1:]), memory)
        return (memory,) + jax.tree.map(cut_time_major, data)

    def _masked_step(self, carry: tuple, batch: tuple, hyper: dict) -> tuple[tuple, dict]:
        """One optimiser step on one minibatch, every transition computed, the inactive ones
        masked out of the losses (:meth:`_loss`)."""
        params, opt_state = carry
        memory, sub, adv, target = batch
        (_, aux), grads = jax.value_and_grad(self._loss, has_aux=True)(
            params, memory, sub, adv, target, hyper)
        return self._apply(params, opt_state, grads, hyper), aux

    def _apply(self, params: Any, opt_state: Any, grads: Any, hyper: dict) -> tuple[Any, Any]:
        """One optimiser step at the lane's learning rate: Adam's step is proportional to its
        learning rate, so the configured schedule's step is scaled by ``hyper learning rate /
        algorithm.learning_rate`` (exactly 1 when the lane keeps the configured rate)."""
        updates, opt_state = self.optimizer.update(grads, opt_state, params)
        if "learning_rate" in self.varied:
            scale = hyper["learning_rate"] / jnp.float32(self.config.algorithm.learning_rate)
            updates = jax.tree.map(lambda u: u * scale, updates)
        return optax.apply_updates(params, updates), opt_state

    # ------------------------------------------------------------------ learning, compacted
    @property
    def _recurrent(self) -> bool:
        """The network carries memory along time (GRU): its unit of work is a sequence."""
        return self.config.network.kind == "gru"

    def _compact_batches(self, order: Array, rollout: Rollout) -> tuple[Array, Array]:
        """Every minibatch of one epoch as the indices of its units, those that can learn
        first: the same minibatches as :meth:`_masked_batches` (the agents in ``order [B]``,
        ``M`` contiguous shares), reordered inside. The data are gathered a chunk at a time
        (:meth:`_unit_data`), only for the chunks that run.

        A unit is one transition for a memoryless network (its row ``t x B + b`` of the
        flattened ``[T x B]`` batch; ``U = T x B / M`` units per minibatch), one agent's whole
        sequence for a GRU (its agent ``b``; ``U = B / M``); it can learn when active (some
        step active, for a sequence). Returns ``(units [M, U], counts [M])``, ``counts`` the
        units that can learn in each minibatch, first in it."""
        minibatches = self.config.algorithm.num_minibatches
        active = rollout.traj.active  # [T, B]
        agents = order.reshape(minibatches, -1)  # [M, B / M]
        if self._recurrent:
            alive = jnp.any(active, axis=0)[agents]  # [M, U]
            return (jnp.take_along_axis(agents, _active_first(alive), axis=1),
                    jnp.sum(alive, axis=1))
        rows = (jnp.arange(active.shape[0])[None, :, None] * self.num_agents
                + agents[:, None, :]).reshape(minibatches, -1)  # [M, U], time-major
        live = active.reshape(-1)[rows]
        return jnp.take_along_axis(rows, _active_first(live), axis=1), jnp.sum(live, axis=1)

    def _take_units(self, x: Array, units: Array) -> Array:
        """The entries of a rollout array ``x [T, B, ...]`` for ``units [C]`` (indices of
        :meth:`_compact_batches`): ``[T, C, ...]`` (agents' sequences) or ``[1, C, ...]``
        (transitions)."""
        if self._recurrent:
            return jnp.take(x, units, axis=1)
        return x.reshape((-1,) + x.shape[2:])[units][None]

    def _unit_data(self, rollout: Rollout, units: Array) -> tuple:
        """The learning data of ``units [C]`` but their advantages (normalised over the whole
        minibatch first: :meth:`_compact_grads`): ``(memory [C, H], traj [T', C, ...],
        targets [T', C])``, ``T' = T`` for a GRU, 1 otherwise (the memoryless network ignores
        the memory: zeros)."""
        if self._recurrent:
            memory = jax.tree.map(lambda c: c[units], rollout.memory)
        else:
            memory = jax.tree.map(lambda c: jnp.zeros(units.shape + c.shape[1:], c.dtype),
                                  rollout.memory)
        return (memory,) + jax.tree.map(lambda x: self._take_units(x, units),
                                        (rollout.traj, rollout.targets))

    def _compact_step(self, carry: tuple, batch: tuple, rollout: Rollout, hyper: dict
                      ) -> tuple[tuple, dict]:
        """One optimiser step on one minibatch of :meth:`_compact_batches`
        (:meth:`_compact_grads`)."""
        params, opt_state = carry
        grads, aux = self._compact_grads(params, batch, rollout, hyper)
        return self._apply(params, opt_state, grads, hyper), aux

    def _compact_grads(self, params: Any, batch: tuple[Array, Array], rollout: Rollout,
                       hyper: dict | None = None) -> tuple[Any, dict]:
        """The loss gradient and terms of one minibatch ``batch = (units [U], count)`` of
        :meth:`_compact_batches`, computing only its first ``count`` units, those that can
        learn: whole chunks of ``chunk = U / COMPACT_CHUNKS`` units, then the rest in half
        chunks (loops whose trip counts are the data's), each gathering its units' data
        (:meth:`_unit_data`) and taking the gradient of its share of the masked losses
        (:meth:`_chunk_loss`), summed. The sum is :meth:`_loss`'s gradient on the same
        minibatch up to float rounding: the losses are sums over transitions divided by
        whole-minibatch counts, and the advantages are normalised over the whole minibatch
        first (they are data, not parameters)."""
        units, count = batch
        chunk, half = compact_chunks(units.shape[0])
        traj = rollout.traj
        adv, counts = _normalised_advantages(
            self._take_units(traj.active, units), self._take_units(traj.decides, units),
            self._take_units(rollout.advantages, units))
        grad_fn = jax.grad(self._chunk_loss, has_aux=True)

        def add(start: Array, size: int, total: tuple) -> tuple:
            memory, sub, targets = self._unit_data(
                rollout, jax.lax.dynamic_slice_in_dim(units, start, size))
            share = jax.lax.dynamic_slice_in_dim(adv, start, size, axis=1)
            grads, aux = grad_fn(params, memory, sub, share, targets, counts, hyper)
            return jax.tree.map(jnp.add, total, (grads, aux))

        zero = (jax.tree.map(jnp.zeros_like, params),
                {name: jnp.zeros((), jnp.float32) for name in LOSS_TERMS})
        whole, rest = compact_trips(count, chunk, half)
        total = jax.lax.fori_loop(0, whole, lambda i, t: add(i * chunk, chunk, t), zero)
        return jax.lax.fori_loop(0, rest, lambda i, t: add(whole * chunk + i * half, half, t),
                                 total)

    def _chunk_loss(self, params: Any, carry: tuple, traj: Transition, adv: Array,
                    targets: Array, counts: tuple[Array, Array], hyper: dict | None = None
                    ) -> tuple[Array, dict]:
        """A chunk's share of :meth:`_loss` (``traj [T', C, ...]``): the sums of its
        transitions' loss terms divided by the whole minibatch's ``counts`` (active, acted),
        with ``adv`` already normalised over the minibatch; the shares of a minibatch's
        chunks add up to its loss."""
        active, acted = counts
        acted_mask = traj.active & traj.decides
        return self._loss_terms(params, carry, traj, adv, targets,
                                lambda x: jnp.sum(x * traj.active) / active,
                                lambda x: jnp.sum(x * acted_mask) / acted, hyper)

    def _learn_lane(self, params: Any, opt_state: Any, key: Array, rollout: Rollout,
                    hyper: dict | None = None) -> tuple[Any, Any, Array, dict]:
        """``learn`` for one lane, as the lane mode compiles it: written as a batch of one
        when sequential (the same values; XLA:CPU then hands every product of the backward
        pass, the weight gradients included, to its fast matmul fusions:
        docs/xla-cpu-learning-layout.md), as is when batched (a ``vmap`` adds the lanes)."""
        hyper = self.default_hyper() if hyper is None else hyper
        if not self.sequential_lanes:
            return self.learn(params, opt_state, key, rollout, hyper)
        one = jax.tree.map(lambda x: x[None], (params, opt_state, key, rollout, hyper))
        return jax.tree.map(lambda x: x[0], jax.vmap(self.learn)(*one))

    def _finish(self, runner: RunnerState, learned: tuple, logs: dict
                ) -> tuple[RunnerState, dict]:
        params, opt_state, key, aux = learned
        runner = runner.replace(params=params, opt_state=opt_state, key=key)
        metrics = {name: jnp.sum(v) for name, v in logs.items()}
        metrics.update({name: jnp.mean(v) for name, v in aux.items()})
        metrics["steps"] = runner.steps
        metrics["num_agents"] = self.num_agents_at(runner.steps)
        return runner, metrics

    def update(self, runner: RunnerState) -> tuple[RunnerState, dict]:
        """One PPO update of one lane: collect ``num_steps`` steps, then learn from them."""
        return self._update(runner, self._learn_lane)

    def _update(self, runner: RunnerState, learn: Any) -> tuple[RunnerState, dict]:
        runner, rollout, logs = self.collect(runner)
        learned = learn(runner.params, runner.opt_state, runner.key, rollout, runner.hyper)
        return self._finish(runner, learned, logs)

    def update_lanes(self, runners: RunnerState) -> tuple[RunnerState, dict]:
        """One update of every lane of ``runners`` (leaves ``[L, ...]``: seeds, ablation
        variants). Batched, or a single lane: one ``vmap`` of the update. Sequential: the
        rollouts as one ``vmap``, the learning phases one lane after another (``lax.map``).
        Metrics ``[L]``."""
        lanes = runners.steps.shape[0]
        if not self.sequential_lanes or lanes == 1:
            return jax.vmap(lambda r: self._update(r, self.learn))(runners)
        runners, rollouts, logs = jax.vmap(self.collect)(runners)
        learned = jax.lax.map(lambda x: self._learn_lane(*x),
                              (runners.params, runners.opt_state, runners.key, rollouts,
                               runners.hyper))
        return jax.vmap(self._finish)(runners, learned, logs)

    def update_chunk(self, runner: RunnerState, count: int) -> tuple[RunnerState, dict]:
        """``count`` updates of one lane in one ``lax.scan`` (metrics stacked ``[count]``)."""
        return jax.lax.scan(lambda r, _: self.update(r), runner, None, count)

    def update_chunk_lanes(self, runners: RunnerState, count: int
                           ) -> tuple[RunnerState, dict]:
        """``count`` updates of every lane (``update_lanes``); metrics ``[L, count]``."""
        runners, metrics = jax.lax.scan(lambda r, _: self.update_lanes(r), runners, None,
                                        count)
        return runners, jax.tree.map(lambda x: jnp.swapaxes(x, 0, 1), metrics)

    def jitted_chunk_lanes(self, count: int, donate: bool = False) -> Callable:
        """``jax.jit`` of :meth:`update_chunk_lanes` of ``count`` updates, as every command
        compiles its training calls (the runner donated if ``donate``): with
        ``sgjax.compilation_cache.learner_compiler_options`` (XLA:CPU's default emitters where
        the command chose the fast-compiling ones for its other programs). One per ``(count,
        donate)`` per trainer, so that callers sharing a trainer (the groups of an ablation)
        trace it once."""
        if (count, donate) not in self._jitted_chunks:
            self._jitted_chunks[count, donate] = jax.jit(
                lambda runners: self.update_chunk_lanes(runners, count),
                donate_argnums=0 if donate else (), compiler_options=learner_compiler_options())
        return self._jitted_chunks[count, donate]

    def train(self, key: Array) -> tuple[RunnerState, dict]:
        """A whole run: ``init`` then every update, one jittable function of the key."""
        return self.update_chunk(self.init(key), self.config.algorithm.num_updates)

    def train_lanes(self, keys: Array) -> tuple[RunnerState, dict]:
        """A whole run of every seed key ``[L, 2]`` as lanes of one function (``train``
        per lane, the lanes run as ``algorithm.lanes`` says)."""
        return self.update_chunk_lanes(jax.vmap(self.init)(keys),
                                       self.config.algorithm.num_updates)

    # ------------------------------------------------------------------ acting
    def policy(self, params: Any, obs_stats: RunningStats, deterministic: bool = False,
               obs_mask: Array | None = None) -> RecurrentPolicy:
        """The trained actor as an ``sgjax.evaluation.evaluate`` policy (any robot count; with
        ``agent_id`` at most the trained number of slots). ``obs_mask`` as in training."""
        return acting_policy(self.config.network, self.actor,
                             ActorWeights(params, obs_stats, obs_mask), deterministic)


def _active_first(mask: Array) -> Array:
    """Indices ``[M, N]`` that put each row of ``mask [M, N]`` (bool) in the order: the true
    entries first, then the false ones, each in their original order (a stable partition:
    ``argsort(~mask, stable=True)``, by running counts and one scatter, 8x faster than the
    sort on XLA:CPU at ``[4, 20480]``)."""
    first = jnp.cumsum(mask, axis=-1) - 1
    rest = jnp.sum(mask, axis=-1, keepdims=True) + jnp.cumsum(~mask, axis=-1) - 1
    where = jnp.where(mask, first, rest)  # each entry's place
    index = jnp.broadcast_to(jnp.arange(mask.shape[-1]), mask.shape)
    rows = jnp.arange(mask.shape[0])[:, None]
    return jnp.zeros_like(index).at[rows, where].set(index, unique_indices=True)


def compact_chunks(units: int) -> tuple[int, int]:
    """The compact learning phase's chunk sizes for a minibatch of ``units`` units: ``(chunk,
    tail)``, ``chunk = units / d`` (``d`` the largest divisor of ``units`` up to
    :data:`COMPACT_CHUNKS`) and ``tail`` half a chunk (a whole one when ``chunk`` is odd): a
    divisor of ``chunk``, so that the tail chunks never run past the minibatch."""
    chunk = units // divisor_up_to(units, COMPACT_CHUNKS)
    return chunk, (chunk // 2 if chunk % 2 == 0 else chunk)


def compact_trips(count: Any, chunk: int, tail: int) -> tuple[Any, Any]:
    """How many whole chunks and then tail chunks compute ``count`` units (ints or arrays):
    ``(count // chunk, ceil((count mod chunk) / tail))``."""
    return count // chunk, -(-(count % chunk) // tail)


def divisor_up_to(n: int, most: int) -> int:
    """The largest divisor of ``n`` that is at most ``most``."""
    return max(d for d in range(1, most + 1) if n % d == 0)


def _normalised_advantages(active: Array, decides: Array, advantages: Array
                           ) -> tuple[Array, tuple[Array, Array]]:
    """A minibatch's advantages normalised over its acted transitions (``active``, and the
    action read: ``decides``; all ``[T', U]``), as :meth:`Trainer._loss` does, and its counts
    of active and of acted transitions (at least 1 each): the whole-minibatch statistics every
    chunk's loss shares."""
    def count(mask: Array) -> Array:
        return jnp.maximum(jnp.sum(mask.astype(jnp.float32)), 1.0)

    acted_mask = (active & decides).astype(jnp.float32)
    acted = count(acted_mask)
    adv_mean = jnp.sum(advantages * acted_mask) / acted
    adv_std = jnp.sqrt(jnp.sum(jnp.square(advantages - adv_mean) * acted_mask) / acted)
    return (advantages - adv_mean) / (adv_std + 1e-8), (count(active), acted)


def _critic_in(traj: Transition) -> Array:
    """The critic's input of stored transitions (the actor's under IPPO, stored once)."""
    return traj.actor_in if traj.critic_in is None else traj.critic_in


def seed_keys(config: TrainConfig) -> Array:
    """One key per seed, ``[num_seeds, 2]`` (seed ``config.seed + i``)."""
    return jax.vmap(jax.random.PRNGKey)(config.seed + jnp.arange(config.num_seeds))

