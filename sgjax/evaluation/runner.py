"""The batched episode runner: ``E`` episodes of one environment under one policy, played as
one ``jit(scan(vmap(step_env)))`` with the metrics accumulated inside.

::

    runner = EpisodeRunner(env, policy, num_episodes=25, max_steps=int(params.max_steps))
    values, robot, states, rewards = runner.run(key, params)  # jitted; params an argument
    batch = runner(key, params)  # compiled, played and brought to the host: Episodes

``params`` is an argument, so one compiled ``run`` serves every robot count up to
``env.max_agents`` (and every pedestrian count, radius or weight the params hold). Steps run
in chunks (:func:`sgjax.kernels.chunked_scan.scan_until_done`) until every episode has ended;
an ended episode's state is frozen, so the results equal those of the whole time limit. With
``counterfactual`` the runner plays the lanes of
:func:`sgjax.evaluation.counterfactual.play_counterfactual` as well; ``record_lanes`` keeps
every state of chosen episodes only (the episode of a GIF, say).

:class:`LaneRunner` plays several policies at several robot counts as the lanes of one loop
(one compiled program for a whole evaluation table)::

    runner = LaneRunner(env, [trained, baseline], num_counts=5, num_episodes=192, max_steps=750,
                        record_lanes=[(2, 0)])  # policy 0 at counts[2], episode 0
    values, robot, *_ = runner.run(key, params, jnp.array([3, 4, 5, 7, 10]))  # [C, E]

:class:`ParamLaneRunner` plays one policy under ``L`` sets of parameters (the seeds or variants
of a training run) as the lanes of one loop, each lane the episodes an ``EpisodeRunner`` of
that lane's policy plays with the same key (inside a ``jit`` whose arguments hold the
parameters)::

    runner = ParamLaneRunner(env, make_policy, lane_params, num_episodes=25, max_steps=750)
    values, robot, *_ = runner.episodes(key, params)  # {name: [L, E]}, {name: [L, E, R]}
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from sgjax.environment.env import SocialNavEnv
from sgjax.evaluation import counterfactual as cf
from sgjax.evaluation import metrics
from sgjax.evaluation.policies import Policy, RecurrentPolicy
from sgjax.kernels.chunked_scan import scan_until_done
from sgjax.types import EnvParams, EnvState, episode_params

__all__ = ["STEP_CHUNK", "EpisodeRunner", "Episodes", "LaneRunner", "ParamLaneRunner",
           "argument_signature", "check_steps", "with_zone_books"]

STEP_CHUNK = 32  # steps per chunk of the runner's early-stopping loop

def argument_signature(args: Any) -> tuple:
    """What arguments must share to be run by one ahead-of-time compiled program: the tree,
    and every leaf's shape, dtype and weak type (a key for caches of compiled programs)."""
    leaves, tree = jax.tree.flatten(args)
    return tree, tuple((np.shape(x), str(x.dtype if hasattr(x, "dtype") else np.asarray(x).dtype),
                        bool(getattr(x, "weak_type", False))) for x in leaves)


_COMPILED: dict[Any, Callable] = {}
KEPT_PROGRAMS = 16  # compiled programs compiled_once keeps (the oldest go first)


def compiled_once(program: Callable, *args: Any) -> tuple[Callable, float]:
    """``program`` (a ``jax.jit`` function) compiled ahead of time for the shapes of ``args``,
    once per process (the last :data:`KEPT_PROGRAMS` kept): ``(executable, seconds this call
    spent compiling)`` (0 when it was compiled before; a program found in the persistent
    compilation cache counts its loading)."""
    key = (program, argument_signature(args))
    if key in _COMPILED:
        return _COMPILED[key], 0.0
    t0 = time.perf_counter()
    compiled = program.lower(*args).compile()
    if len(_COMPILED) >= KEPT_PROGRAMS:  # dicts keep insertion order: drop the oldest
        del _COMPILED[next(iter(_COMPILED))]
    _COMPILED[key] = compiled
    return compiled, time.perf_counter() - t0


def lanes_first(tree: Any, episodes: int, lanes: int) -> Any:
    """Rows ``[E * L, ...]`` (episode-major, as the runner's loop holds them) -> ``[L, E,
    ...]``, every leaf of ``tree``."""
    return jax.tree.map(lambda v: jnp.swapaxes(v.reshape((episodes, lanes) + v.shape[1:]), 0, 1),
                        tree)


def with_zone_books(env: SocialNavEnv) -> SocialNavEnv:
    """The same environment, keeping conflict-zone books for the order-violation metrics."""
    if env.config.track_zones:
        return env
    return SocialNavEnv(dataclasses.replace(env.config, track_zones=True), env.default_params)


def check_steps(params: EnvParams, num_steps: int, where: str) -> None:
    """Raise unless episodes under ``params`` end within ``num_steps`` steps (the length a
    runner was built for)."""
    if int(params.max_steps) > num_steps:
        raise ValueError(f"{where}: these params run episodes of {int(params.max_steps)} steps, "
                         f"but the runner was built for {num_steps} (a longer time limit needs "
                         "its own runner)")


@dataclasses.dataclass
class Episodes:
    """Host results of a batch of ``E`` episodes."""

    values: dict[str, np.ndarray]  # per-episode value of every metric, [E]
    robot: dict[str, np.ndarray]  # per-robot values of robot-level metrics, [E, R]
    # with record=True: EnvState stacked [T + 1, E, ...] (T = time limit); with record_lanes:
    # [T + 1, len(record_lanes), ...], the recorded episodes in the order given
    states: Any = None
    # with either: each robot's reward at every step [T, E or len(record_lanes), R] (row t is
    # the step from states[t] to states[t + 1]; 0 once the episode has ended)
    rewards: np.ndarray | None = None
    compile_seconds: float | None = None  # compiling the batched run
    run_seconds: float | None = None  # running it once compiled (results on the host)


class LoopCarry(NamedTuple):
    """What the runner's loop carries, every leaf ``[E * L, ...]`` (``L`` lanes per episode)."""

    obs: Array  # [N, R, D]
    state: EnvState
    tally: metrics.MetricState
    memory: Any  # the policy's (zeros for a policy without memory)
    extra: Any  # what a hook folds the steps into (the counterfactual comparisons)
    reward: Array  # [N, R] each robot's reward at the last step (0 once its episode ended)


def act(policy: Policy | RecurrentPolicy, memory: Any, obs: Array, keys: Array,
        state: EnvState, params: EnvParams) -> tuple[Any, Array]:
    """``policy`` for every environment of a batch: ``obs [N, R, D]``, ``keys [N]``, ``state``
    with leading axis ``N`` -> ``(memory, actions)``, actions ``[N, R]`` (GO/STOP) or
    ``[N, R, d]``; ``memory`` (``[N, ...]``) passes through for a policy without memory. Each
    environment's policy sees its episode's params (its generated world's map, if any)."""
    if isinstance(policy, RecurrentPolicy):
        return jax.vmap(lambda c, o, k, s: policy.step(c, o, k, s, episode_params(s, params)))(
            memory, obs, keys, state)
    return memory, jax.vmap(lambda o, k, s: policy(o, k, s, episode_params(s, params)))(
        obs, keys, state)


def first_memory(policy: Policy | RecurrentPolicy, count: int, num_robots: int) -> Any:
    """The memory of ``count`` episodes at their start: ``policy.init(num_robots)`` stacked
    ``[count, ...]``, or zeros ``[count]`` for a policy without memory."""
    if isinstance(policy, RecurrentPolicy):
        return jax.vmap(lambda _: policy.init(num_robots))(jnp.arange(count))
    return jnp.zeros(count)


def _checked_lanes(lanes: Sequence[int] | None, count: int, what: str) -> tuple[int, ...] | None:
    """``lanes`` as a tuple of indices in ``[0, count)`` (None stays None)."""
    if lanes is None:
        return None
    lanes = tuple(int(i) for i in lanes)
    if not lanes or not all(0 <= i < count for i in lanes):
        raise ValueError(f"{what} must be a non-empty list of indices in [0, {count}), got "
                         f"{list(lanes)}")
    return lanes


def with_first_state(recorder: Callable[..., Any] | None, first: EnvState, recorded: Any
                     ) -> tuple[Any, Any]:
    """``(states [T + 1, ...], rewards [T, ..., R])``: the recorded steps ``(states [T, ...],
    rewards)`` with the state after the reset (``first``, batched) before them; ``(None,
    None)`` when nothing was recorded."""
    if recorder is None:
        return None, None
    states, rewards = recorded
    start, _ = recorder(first)
    return jax.tree.map(lambda a, rest: jnp.concatenate([a[None], rest]), start,
                        states), rewards


class EpisodeRunner:
    """Plays ``num_episodes`` episodes of ``env`` under ``policy`` for ``max_steps`` steps.

    ``env`` gets conflict-zone books (:func:`with_zone_books`); ``policy`` is a
    ``policy(obs, key, state, params) -> actions`` or a :class:`RecurrentPolicy`. ``record``
    keeps every step's state of every episode (and plays the whole time limit);
    ``record_lanes`` (episode indices) keeps every step's state of those episodes only
    (``[T + 1, len(record_lanes), ...]``, a few MB for one episode) and still stops early, so a
    run can both evaluate and record the episode a picture is drawn from. ``counterfactual``
    also plays every episode with each robot alone and without each robot (``1 + 2R`` times
    the work) and fills in the counterfactual metrics (NaN otherwise; every other metric is the
    same either way). ``stop_early=False`` steps through the whole time limit (same results;
    for benchmarks of the step). :attr:`run` is ``jit(episodes)``, compiled once per shape."""

    def __init__(self, env: SocialNavEnv, policy: Policy | RecurrentPolicy, num_episodes: int,
                 max_steps: int, constants: metrics.MetricConstants = metrics.DEFAULT_CONSTANTS,
                 record: bool = False, counterfactual: bool = False, stop_early: bool = True,
                 record_lanes: Sequence[int] | None = None):
        if num_episodes < 1:
            raise ValueError(f"num_episodes must be at least 1, got {num_episodes}")
        if record and record_lanes is not None:
            raise ValueError("record keeps every episode and record_lanes some: give one")
        self.env = with_zone_books(env)
        self.policy, self.num_episodes, self.num_steps = policy, num_episodes, int(max_steps)
        self.num_robots = self.env.max_agents
        self.constants, self.record, self.counterfactual = constants, record, counterfactual
        self.record_lanes = _checked_lanes(record_lanes, num_episodes, "record_lanes")
        self.every_step = record or not stop_early
        self.run = jax.jit(self.episodes)
        self._executables: dict[Any, Callable] = {}  # compiled run by argument signature

    def reset_lanes(self, keys: Array, params: EnvParams, keep: Array
                    ) -> tuple[Array, EnvState]:
        """``env.reset_subset`` for every lane: ``keys [N]``, ``keep [N, R]``."""
        return jax.vmap(self.env.reset_subset, in_axes=(0, None, 0))(keys, params, keep)

    def finalize(self, tally: metrics.MetricState, final: EnvState, params: EnvParams
                 ) -> tuple[dict[str, Array], dict[str, Array]]:
        """:func:`sgjax.evaluation.metrics.finalize` of every lane."""
        return jax.vmap(metrics.finalize, in_axes=(0, 0, None))(tally, final, params)

    def _act(self, memory: Any, obs: Array, keys: Array, state: EnvState, params: EnvParams
             ) -> tuple[Any, Array]:
        return act(self.policy, memory, obs, keys, state, params)

    def _first_memory(self, count: int) -> Any:
        return first_memory(self.policy, count, self.num_robots)

    def _recorder(self) -> Callable[..., Any] | None:
        """What the loop keeps of each step's batched state ``[N, ...]`` and rewards ``[N, R]``
        (``recorder(state, reward) -> (state, reward)``): all of them (``record``), the
        ``record_lanes`` rows, or nothing (None)."""
        if self.record:
            return lambda s, r=None: (s, r)
        if self.record_lanes is None:
            return None
        rows = np.asarray(self.record_lanes)
        return lambda s, r=None: jax.tree.map(lambda leaf: leaf[rows], (s, r))

    def play(self, params: EnvParams, obs: Array, state: EnvState, lanes: int,
             step_keys: Array, hook: Callable | None = None, extra: Any = None,
             emit: Callable | None = None) -> tuple[EnvState, metrics.MetricState, Any, Any]:
        """Play ``num_episodes x lanes`` episodes (episode-major) from ``obs, state`` for the
        time limit; the lanes of an episode share its per-step keys (``step_keys [T]``).
        ``hook(extra, prev, state, running)`` folds each step into ``extra``;
        ``emit(state, reward)`` (the state after each step, the step's rewards ``[N, R]``) is
        returned for every step ``[T, ...]``. Returns ``(final, tally, extra, out)``."""
        count, episodes, constants = self.num_episodes * lanes, self.num_episodes, self.constants
        step = jax.vmap(self.env.step_env, in_axes=(0, 0, 0, None))
        update = jax.vmap(lambda m, s0, s1, info, done: metrics.update(
            m, s0, s1, info, done, params, constants))
        num_zones = state.zones.phase.shape[-1]
        tally = jax.vmap(lambda _: metrics.start(self.num_robots, constants, num_zones))(
            jnp.arange(count))

        def per_lane(keys: Array) -> Array:
            return keys if lanes == 1 else keys[jnp.arange(count) // lanes]

        def one_step(c: LoopCarry, key: Array) -> LoopCarry:
            k_act, k_step = jax.random.split(key)
            memory, actions = self._act(c.memory, c.obs,
                                        per_lane(jax.random.split(k_act, episodes)), c.state,
                                        params)
            next_obs, next_state, reward, term, trunc, info = step(
                per_lane(jax.random.split(k_step, episodes)), c.state, actions, params)
            done = jax.vmap(metrics.episode_done)(next_state, term, trunc)
            tally_next = update(c.tally, c.state, next_state, info, done)

            def keep(new: Array, old: Array) -> Array:  # ended episodes stay as they ended
                running = c.tally.running.reshape((-1,) + (1,) * (new.ndim - 1))
                return jnp.where(running, new, old)

            kept = jax.tree.map(keep, next_state, c.state)
            extra = c.extra if hook is None else hook(c.extra, c.state, kept, c.tally.running)
            reward = jnp.where(c.tally.running[:, None], reward, 0.0)
            return LoopCarry(keep(next_obs, c.obs), kept, tally_next, memory, extra, reward)

        start = LoopCarry(obs, state, tally, self._first_memory(count), extra,
                          jnp.zeros((count, self.num_robots), jnp.float32))
        final, out, _ = scan_until_done(
            one_step, start, lambda c: ~jnp.any(c.tally.running), self.num_steps, STEP_CHUNK,
            xs=step_keys, record=None if emit is None else (lambda c: emit(c.state, c.reward)),
            stop_early=not self.every_step)
        return final.state, final.tally, final.extra, out

    def episode_keys(self, key: Array) -> tuple[Array, Array]:
        """``(reset_keys [E], step_keys [T])`` of ``key``: episode ``e`` resets with
        ``reset_keys[e]``, and every episode's step ``t`` draws from ``step_keys[t]``."""
        k_reset, k_steps = jax.random.split(key)
        return (jax.random.split(k_reset, self.num_episodes),
                jax.random.split(k_steps, self.num_steps))

    def reset_batch(self, keys: Array, params: EnvParams, *args: Any
                    ) -> tuple[Array, EnvState]:
        """``env.reset`` of every episode (``keys [E]``); a subclass that plays chosen worlds
        resets into them from its extra :attr:`run` arguments ``args``."""
        return jax.vmap(self.env.reset, in_axes=(0, None))(keys, params)

    def episodes(self, key: Array, params: EnvParams, *args: Any) -> tuple:
        """``(values, robot, states, rewards)``: every metric per episode ``{name: [E]}`` and
        per robot ``{name: [E, R]}``; with ``record`` the states ``[T + 1, E, ...]`` (the reset
        first) and each step's rewards ``[T, E, R]``, with ``record_lanes`` those episodes'
        ``[T + 1, len(record_lanes), ...]`` and ``[T, len(record_lanes), R]``, else None.
        Traceable: :attr:`run` is its ``jit``; ``params.max_steps`` must be at most
        ``max_steps`` (:func:`check_steps`), as an episode is cut off there."""
        reset_keys, step_keys = self.episode_keys(key)
        recorder = self._recorder()
        if self.counterfactual:
            robot, episode, recorded, first = cf.play_counterfactual(
                self, reset_keys, step_keys, params, recorder is not None)
            if self.record_lanes is not None:  # the lanes' rows of every recorded step
                rows = np.asarray(self.record_lanes)
                recorded = jax.tree.map(lambda leaf: leaf[:, rows], recorded)
        else:
            obs, first = self.reset_batch(reset_keys, params, *args)
            final, tally, _, recorded = self.play(params, obs, first, 1, step_keys,
                                                  emit=recorder)
            robot, episode = self.finalize(tally, final, params)
        values = jax.vmap(metrics.per_episode)(robot, episode)
        return values, robot, *with_first_state(recorder, first, recorded)

    def compile(self, key: Array, params: EnvParams, *args: Any) -> tuple[Callable, float]:
        """:attr:`run` compiled for the shapes of its arguments (``key``, ``params`` and, for a
        :class:`LaneRunner`, the counts), and the seconds it took."""
        t0 = time.perf_counter()
        compiled = self.run.lower(key, params, *args).compile()
        return compiled, time.perf_counter() - t0

    def play_compiled(self, compiled: Callable, key: Array, params: EnvParams,
                      compile_seconds: float | None = None, args: tuple = ()) -> Episodes:
        """Run a compiled :attr:`run` (on ``key, params, *args``) and bring its results to the
        host, timed."""
        check_steps(params, self.num_steps, type(self).__name__)
        t0 = time.perf_counter()
        values, robot, states, rewards = jax.device_get(compiled(key, params, *args))
        return Episodes(values={k: np.asarray(v) for k, v in values.items()},
                        robot={k: np.asarray(v) for k, v in robot.items()}, states=states,
                        rewards=None if rewards is None else np.asarray(rewards),
                        compile_seconds=compile_seconds, run_seconds=time.perf_counter() - t0)

    def __call__(self, key: Array, params: EnvParams, *args: Any) -> Episodes:
        """Compile for these shapes (once per runner: a later call with arguments of the same
        shapes and dtypes, other params values say, plays the same program and reports
        ``compile_seconds`` 0), play, and return the host results."""
        signature = argument_signature((key, params, *args))
        compiled = self._executables.get(signature)
        seconds = 0.0
        if compiled is None:
            compiled, seconds = self.compile(key, params, *args)
            self._executables[signature] = compiled
        return self.play_compiled(compiled, key, params, seconds, args)


class LaneRunner(EpisodeRunner):
    """Every policy of ``policies`` (``P``) at every robot count of ``counts`` (``K``, an
    argument of :attr:`run`, ``[K]`` int32): ``C = P x K`` configurations of ``num_episodes``
    episodes each, played as the lanes of one loop, so one compiled program evaluates them all.

    Configuration ``c = p * K + k`` is policy ``p`` with ``counts[k]`` robots. Each plays the
    episodes an :class:`EpisodeRunner` of its policy plays with the same key and the params at
    that count (``num_agents = counts[k]``, ``min_agents`` 0, as
    :func:`sgjax.evaluation.evaluate.params_by_count` makes them): episode ``e`` of every
    configuration has the same reset and per-step keys. The count is read at the reset only,
    so the configurations share ``params`` otherwise. Each policy acts on its own
    configurations' lanes (a static slice: no policy spends work on another's lanes); the
    policies must give actions of one shape. The loop stops once every episode of every
    configuration has ended (an ended episode is frozen, so the results do not depend on when).
    ``record_lanes``: ``(configuration, episode)`` pairs whose every state is kept.

    ``run(key, params, counts) -> (values, robot, states)``: every metric per episode
    ``{name: [C, E]}`` and per robot ``{name: [C, E, R]}``; ``states`` the recorded lanes'
    ``[T + 1, len(record_lanes), ...]`` (None without ``record_lanes``). Calling the runner
    gives :class:`Episodes` with those ``[C, E]`` values."""

    def __init__(self, env: SocialNavEnv, policies: Sequence[Policy | RecurrentPolicy],
                 num_counts: int, num_episodes: int, max_steps: int,
                 constants: metrics.MetricConstants = metrics.DEFAULT_CONSTANTS,
                 record_lanes: Sequence[tuple[int, int]] | None = None,
                 stop_early: bool = True):
        if not policies or num_counts < 1:
            raise ValueError(f"LaneRunner needs policies and counts, got {len(policies)} "
                             f"policies and {num_counts} counts")
        super().__init__(env, policies[0], num_episodes, max_steps, constants,
                         stop_early=stop_early)
        self.policies, self.num_counts = tuple(policies), int(num_counts)
        self.num_configs = len(self.policies) * self.num_counts
        if record_lanes is not None:
            pairs = [(int(c), int(e)) for c, e in record_lanes]
            if not pairs or not all(0 <= c < self.num_configs and 0 <= e < num_episodes
                                    for c, e in pairs):
                raise ValueError(f"record_lanes must be (configuration < {self.num_configs}, "
                                 f"episode < {num_episodes}) pairs, got {pairs}")
            self.record_lanes = tuple(e * self.num_configs + c for c, e in pairs)

    def _block(self, p: int) -> Callable[[Array], Array]:
        """The rows ``[E * K, ...]`` of policy ``p``'s configurations in a batch of the loop's
        episode-major ``[E * C, ...]`` rows."""
        episodes, k = self.num_episodes, self.num_counts

        def take(leaf: Array) -> Array:
            lanes = leaf.reshape((episodes, self.num_configs) + leaf.shape[1:])
            return lanes[:, p * k:(p + 1) * k].reshape((episodes * k,) + leaf.shape[1:])

        return take

    def _act(self, memory: Any, obs: Array, keys: Array, state: EnvState, params: EnvParams
             ) -> tuple[Any, Array]:
        memories, actions = [], []
        for p, policy in enumerate(self.policies):
            take = self._block(p)
            m, a = act(policy, memory[p], take(obs), take(keys), jax.tree.map(take, state),
                       params)
            memories.append(m)
            actions.append(a.reshape((self.num_episodes, self.num_counts) + a.shape[1:]))
        if len({a.shape for a in actions}) > 1:
            raise ValueError("LaneRunner: the policies give actions of different shapes "
                             f"{[a.shape[2:] for a in actions]}; they must act in one "
                             "environment")
        dtype = jnp.result_type(*actions)
        joined = jnp.concatenate([a.astype(dtype) for a in actions], axis=1)
        return tuple(memories), joined.reshape((self.num_episodes * self.num_configs,)
                                               + joined.shape[2:])

    def _first_memory(self, count: int) -> Any:
        return tuple(first_memory(policy, self.num_episodes * self.num_counts, self.num_robots)
                     for policy in self.policies)

    def episodes(self, key: Array, params: EnvParams, counts: Array) -> tuple:
        """See the class: ``counts [K]`` robot counts, each at most ``env.max_agents``."""
        reset_keys, step_keys = self.episode_keys(key)
        per_config = jnp.tile(jnp.asarray(counts, jnp.int32), len(self.policies))
        exact = jnp.zeros((), jnp.int32)

        def reset(k: Array, n: Array) -> tuple[Array, EnvState]:
            return self.env.reset(k, params.replace(num_agents=n, min_agents=exact))

        obs, first = jax.vmap(jax.vmap(reset, in_axes=(None, 0)), in_axes=(0, None))(
            reset_keys, per_config)  # [E, C, ...]
        obs, first = jax.tree.map(lambda v: v.reshape((v.shape[0] * v.shape[1],) + v.shape[2:]),
                                  (obs, first))
        recorder = self._recorder()
        final, tally, _, recorded = self.play(params, obs, first, self.num_configs, step_keys,
                                              emit=recorder)
        robot, episode = self.finalize(tally, final, params)
        values = jax.vmap(metrics.per_episode)(robot, episode)
        return (*lanes_first((values, robot), self.num_episodes, self.num_configs),
                *with_first_state(recorder, first, recorded))


class ParamLaneRunner(EpisodeRunner):
    """One policy under ``L`` sets of parameters: ``make_policy(lane)`` builds lane ``l``'s
    policy from ``lane`` (the ``l``-th slice of ``lane_params``, a pytree whose every leaf has
    a leading ``[L]`` axis: a training run's seeds, say, or its variants' weights). Every lane
    plays the ``num_episodes`` episodes an :class:`EpisodeRunner` of its policy plays with the
    same key (same resets, same per-step keys), and the lanes run inside one loop (``E x L``
    episodes, episode-major) that stops once every episode of every lane has ended.

    This is what ``vmap`` of an ``EpisodeRunner`` over the lanes computes, without batching the
    episode loop: under ``vmap`` the loop's stop test becomes per lane, and JAX turns every
    carried leaf into a select and traces the loop body again for each batching pass; here
    only the policy is ``vmap``-ed (over the lanes, once per step), so there is less to trace,
    lower and compile (``bench/compile_time.py`` measures it).

    ``episodes(key, params) -> (values, robot, None)``: every metric per lane and episode
    ``{name: [L, E]}`` and per robot ``{name: [L, E, R]}``. Build it where ``lane_params`` are
    traced (inside the ``jit`` that takes them as arguments): :attr:`run` closes over them."""

    def __init__(self, env: SocialNavEnv, make_policy: Callable[[Any], Policy | RecurrentPolicy],
                 lane_params: Any, num_episodes: int, max_steps: int,
                 constants: metrics.MetricConstants = metrics.DEFAULT_CONSTANTS):
        sizes = {int(np.shape(leaf)[0]) if np.ndim(leaf) else -1
                 for leaf in jax.tree.leaves(lane_params)}
        if len(sizes) != 1 or min(sizes) < 1:
            raise ValueError("ParamLaneRunner: every leaf of lane_params needs the same leading "
                             f"lanes axis, got leading sizes {sorted(sizes)}")
        self.make_policy, self.lane_params = make_policy, lane_params
        self.num_lanes = sizes.pop()
        # no single policy: _act and _first_memory build each lane's from its parameters
        super().__init__(env, None, num_episodes, max_steps, constants)

    def _by_lane(self, tree: Any) -> Any:
        """Rows ``[E * L, ...]`` (episode-major) -> ``[E, L, ...]``."""
        return jax.tree.map(lambda v: v.reshape((self.num_episodes, self.num_lanes)
                                                + v.shape[1:]), tree)

    def _by_row(self, tree: Any) -> Any:
        """``[E, L, ...]`` -> rows ``[E * L, ...]``."""
        return jax.tree.map(lambda v: v.reshape((v.shape[0] * v.shape[1],) + v.shape[2:]),
                            tree)

    def _act(self, memory: Any, obs: Array, keys: Array, state: EnvState, params: EnvParams
             ) -> tuple[Any, Array]:
        def lane(lane_params: Any, memory: Any, obs: Array, keys: Array, state: EnvState
                 ) -> tuple[Any, Array]:
            return act(self.make_policy(lane_params), memory, obs, keys, state, params)

        memory, actions = jax.vmap(lane, in_axes=(0, 1, 1, 1, 1), out_axes=1)(
            self.lane_params, *self._by_lane((memory, obs, keys, state)))
        return self._by_row((memory, actions))

    def _first_memory(self, count: int) -> Any:
        memory = jax.vmap(lambda lane: first_memory(self.make_policy(lane), self.num_episodes,
                                                    self.num_robots),
                          out_axes=1)(self.lane_params)
        return self._by_row(memory)

    def episodes(self, key: Array, params: EnvParams) -> tuple:
        """See the class."""
        reset_keys, step_keys = self.episode_keys(key)
        obs, first = jax.vmap(self.env.reset, in_axes=(0, None))(reset_keys, params)
        obs, first = jax.tree.map(lambda v: jnp.repeat(v, self.num_lanes, axis=0), (obs, first))
        final, tally, _, _ = self.play(params, obs, first, self.num_lanes, step_keys)
        robot, episode = self.finalize(tally, final, params)
        values = jax.vmap(metrics.per_episode)(robot, episode)
        return (*lanes_first((values, robot), self.num_episodes, self.num_lanes), None, None)
