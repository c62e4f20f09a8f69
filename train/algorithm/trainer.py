"""IPPO and MAPPO with parameter sharing, as jitted functions (the purejaxrl shape).

Every robot slot of every environment is one agent of a shared network; agents are laid out
``B = num_envs x slots``. One update collects ``num_steps`` steps of the whole batch with
``lax.scan`` (auto-reset inside the environment; :mod:`train.algorithm.rollout`), computes GAE
(:mod:`train.algorithm.gae`), and runs ``update_epochs`` passes of ``num_minibatches``
minibatches over agent sequences (:mod:`train.algorithm.learner`, losses in
:mod:`train.algorithm.losses`). Robots that are absent or have finished (``info["was_active"]``
false) are masked out of every loss and statistic.

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
``update_chunk_lanes`` give the same run in pieces (:mod:`train.run.loop` runs them for every
command: progress, evaluation and checkpoints between the pieces).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax import Array

from sgjax.compilation_cache import learner_compiler_options
from sgjax.evaluation.policies import RecurrentPolicy
from sgjax.evaluation.runner import compiled_once
from sgjax.terms.base import ConfigError
from train.algorithm.actor import ActorLayout, ActorWeights, TrainedActor, acting_policy
from train.algorithm.config import TrainConfig, resolved_compact, resolved_lanes
from train.algorithm.env_batch import EnvBatch, observation_mask
from train.algorithm.lane_settings import LaneSettings
from train.algorithm.learner import Learner
from train.algorithm.networks import ActorCritic, initial_carry, most_seen, others_layout
from train.algorithm.normalize import RunningStats
from train.algorithm.rollout import RolloutParts, collect
from train.algorithm.state import Rollout, RunnerState
from train.algorithm.world_curriculum import empty_buffers


class Trainer:
    """Builds the environment batch, the network and the optimiser from a ``TrainConfig``, and
    runs updates of one lane or of many.

    Its parts are public: ``rollout_parts`` (:func:`train.algorithm.rollout.collect` reads
    them), ``learner`` (:class:`train.algorithm.learner.Learner`), ``settings``
    (:class:`train.algorithm.lane_settings.LaneSettings`)."""

    def __init__(self, config: TrainConfig, varied: Sequence[str] = ()):
        """``varied``: the lane settings (:data:`~train.algorithm.lane_settings.LANE_SETTINGS`)
        that lanes of one call may set differently from ``config`` (``train.sweep`` names
        them): the program reads those from each lane's runner state (``RunnerState.hyper``)
        and the others as constants of the config, so a run that varies nothing is the
        program it always was. With ``team_reward`` among them every lane mixes its rewards
        (by its own share, 0 included); else only a config with a share above 0 does."""
        self.settings = LaneSettings(config.algorithm, varied)
        self.varied = self.settings.varied
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
        self.rollout_parts = RolloutParts(
            batch=self.batch, network=self.network, network_config=config.network,
            layout=self.actor, algorithm=a, settings=self.settings, mappo=self.mappo,
            stage_steps=jnp.asarray([s for s, _ in stages], jnp.int32),
            stage_counts=jnp.asarray([n for _, n in stages], jnp.int32),
            levels=config.levels)
        self.learner = Learner(self.network, self.optimizer, a, self.settings, self.num_agents,
                               self.batch.discrete, self.compact,
                               recurrent=config.network.recurrent)
        self._fresh_run = jax.jit(self._start)

    # ------------------------------------------------------------------ inputs
    def num_agents_at(self, steps: Array) -> Array:
        """The curriculum's robot count after ``steps`` environment steps."""
        return self.rollout_parts.num_agents_at(steps)

    def inputs(self, obs_stats: RunningStats, obs: Array) -> tuple[Array, Array]:
        """Actor and critic inputs ``[B, .]`` for a batch ``obs [E, R, D]``."""
        return self.rollout_parts.inputs(obs_stats, obs)

    def default_hyper(self) -> dict[str, Array]:
        """The configured lane settings, float32 (:meth:`LaneSettings.defaults`)."""
        return self.settings.defaults()

    def lane_hyper(self, values: dict[str, float]) -> dict[str, np.ndarray]:
        """A lane's ``hyper`` for :meth:`init` (:meth:`LaneSettings.lane`)."""
        return self.settings.lane(values)

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

    # ------------------------------------------------------------------ init
    def init(self, key: Array, term_weights: dict | None = None, obs_mask: Array | None = None,
             hyper: dict | None = None, curriculum: dict | None = None) -> RunnerState:
        """A fresh run. ``term_weights`` ({reward term: multiplier}, default the config's),
        ``obs_mask`` (``[D]``, default :meth:`observation_mask`), ``hyper`` ({lane setting:
        value}, default the config's) and ``curriculum`` (a curriculum's numbers,
        :meth:`curriculum_values`, default the config method's) are arrays in the state, so a
        ``vmap`` over them trains reward and observation ablations, hyper-parameter trials and
        curricula at once."""
        weights = self.term_weights()
        for name, value in (term_weights or {}).items():
            if name not in weights:
                raise ConfigError(f"term_weights: unknown reward term {name!r}; this "
                                  f"configuration pays {list(weights)}")
            weights[name] = jnp.asarray(value, jnp.float32)
        mask = jnp.asarray(self.observation_mask() if obs_mask is None else obs_mask)
        if curriculum is None:
            curriculum = self.curriculum_values()
        elif curriculum and not self.config.levels.active:
            raise ConfigError("init(curriculum=...): this config has no curriculum over "
                              "generated worlds (levels.method 'dr'); set levels.method")
        return self._fresh_run(key, weights, mask, self.settings.with_values(hyper),
                               dict(curriculum))

    def curriculum_values(self, method: str | None = None) -> dict[str, Array]:
        """A lane's curriculum numbers for ``method`` (default the config's; float32,
        :meth:`train.algorithm.config.LevelsConfig.lane_values`), ``{}`` without a
        curriculum."""
        if not self.config.levels.active:
            if method not in (None, "dr"):
                raise ConfigError(f"levels.method {method!r} for a lane: this config has no "
                                  "curriculum over generated worlds (levels.method 'dr')")
            return {}
        return {name: jnp.float32(value)
                for name, value in self.config.levels.lane_values(method).items()}

    def _start(self, key: Array, weights: dict, mask: Array, hyper: dict,
               curriculum: dict) -> RunnerState:
        """``init``'s body, compiled (``_fresh_run``): called eagerly, the network and
        environment initialisation would run op by op."""
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
            term_weights=weights, obs_mask=mask, hyper=hyper,
            levels=empty_buffers(self.batch, self.config.levels), curriculum=curriculum)

    # ------------------------------------------------------------------ updates
    def collect(self, runner: RunnerState) -> tuple[RunnerState, Rollout, dict]:
        """The rollout half of an update (:func:`train.algorithm.rollout.collect`)."""
        return collect(self.rollout_parts, runner)

    def learn(self, params: Any, opt_state: Any, key: Array, rollout: Rollout,
              hyper: dict | None = None) -> tuple[Any, Any, Array, dict]:
        """The learning half of an update (:meth:`train.algorithm.learner.Learner.learn`;
        ``hyper`` default the config's)."""
        hyper = self.default_hyper() if hyper is None else hyper
        return self.learner.learn(params, opt_state, key, rollout, hyper)

    def learn_lane(self, params: Any, opt_state: Any, key: Array, rollout: Rollout,
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
        return self._update(runner, self.learn_lane)

    def _update(self, runner: RunnerState, learn: Callable) -> tuple[RunnerState, dict]:
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
        learned = jax.lax.map(lambda x: self.learn_lane(*x),
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
        ``sgjax.compilation_cache.learner_compiler_options``. One per ``(count, donate)`` per
        trainer, so that callers sharing a trainer (the groups of an ablation) trace it
        once."""
        if (count, donate) not in self._jitted_chunks:
            self._jitted_chunks[count, donate] = jax.jit(
                lambda runners: self.update_chunk_lanes(runners, count),
                donate_argnums=0 if donate else (), compiler_options=learner_compiler_options())
        return self._jitted_chunks[count, donate]

    def compiled_chunk_lanes(self, count: int, runners: RunnerState, donate: bool = False
                             ) -> tuple[Callable, float]:
        """:meth:`jitted_chunk_lanes` compiled ahead of time for the shapes of ``runners``
        (:func:`sgjax.evaluation.runner.compiled_once`): ``(executable, seconds this call
        spent compiling)``."""
        return compiled_once(self.jitted_chunk_lanes(count, donate), runners)

    def train(self, key: Array) -> tuple[RunnerState, dict]:
        """A whole run: ``init`` then every update, one jittable function of the key."""
        return self.update_chunk(self.init(key), self.config.algorithm.num_updates)

    def train_lanes(self, keys: Array) -> tuple[RunnerState, dict]:
        """A whole run of every seed key ``[L, 2]`` as lanes of one function (``train``
        per lane, the lanes run as ``algorithm.lanes`` says)."""
        return self.update_chunk_lanes(jax.vmap(self.init)(keys),
                                       self.config.algorithm.num_updates)

    # ------------------------------------------------------------------ acting
    @property
    def trained_actor(self) -> TrainedActor:
        """The actor's network and layout, for
        :class:`sgjax.evaluation.trained.TrainedEvaluation`."""
        return TrainedActor(self.config.network, self.actor)

    def policy(self, params: Any, obs_stats: RunningStats, deterministic: bool = False,
               obs_mask: Array | None = None) -> RecurrentPolicy:
        """The trained actor as an ``sgjax.evaluation.evaluate`` policy (any robot count; with
        ``agent_id`` at most the trained number of slots). ``obs_mask`` as in training."""
        return acting_policy(self.config.network, self.actor,
                             ActorWeights(params, obs_stats, obs_mask), deterministic)


def seed_keys(config: TrainConfig) -> Array:
    """One key per seed, ``[num_seeds, 2]`` (seed ``config.seed + i``)."""
    return jax.vmap(jax.random.PRNGKey)(config.seed + jnp.arange(config.num_seeds))
