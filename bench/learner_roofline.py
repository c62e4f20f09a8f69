"""Learner roofline: where one PPO update's time goes, phase by phase, against this machine's
measured peaks.

Prints, in one run:

* the peaks: a jitted 1024 x 1024 float32 matmul (GFLOP/s), and the forward and backward pass
  of plain ``tanh`` MLPs at the trainer's exact shapes (an actor and a critic tower of the
  configured widths on one minibatch's rows, ``num_envs x slots x num_steps /
  num_minibatches``);
* for each network asked for (``mlp``; ``gru``: ``network.kind: gru``; ``lstm``: the MLP with
  ``network.others_encoder: lstm``, CADRL(L)'s encoder) the trainer's phases, each compiled
  alone at the trainer's shapes and in its layout (a lane of one, as a one-seed run compiles
  its update): the environment step, the policy forward pass of the rollout (acting, and the
  critic's bootstrap value of the final observations of the truncating environments), the
  observation and return
  normalisation, GAE, the minibatch gradients (masked, and ``algorithm.compact``), the
  optimiser, the learning phase's shuffle and gather, and the rest of the measured update
  (scan bookkeeping, rewards, logs, what compiling the phases together adds or saves), in
  seconds per update, GFLOP per update (XLA's cost analysis of each phase compiled alone; a
  loop's body counts once there, so a phase's FLOPs are its body's times its trip count, the
  GRU's gradient counted on its rows as sequences of one step), GFLOP/s and as a share of the
  two peaks; then the host's work per call of the command line's chunk of updates (dispatch,
  and fetching the logs), whole updates with ``algorithm.compact`` off and on, and the
  update's two halves (the rollout, the learning phase) as the update compiles them.

The configuration is the README's main job (``train/configs/doorway.yaml``: 256 environments
x 64 steps x 5 robot slots, 4 epochs x 4 minibatches, MLP 128 x 128, GO/STOP) with the options
below applied. Timings are the best of a few calls after a warm-up; on a shared machine they
move with its load.

    python bench/learner_roofline.py
    python bench/learner_roofline.py --network mlp --num-envs 64 --robots 4
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from compiled import compile_measured

from train.algorithm.actor import head_log_std
from train.algorithm.config import TrainConfig, load_config
from train.algorithm.gae import gae
from train.algorithm.learner import compact_chunks, compact_trips
from train.algorithm.networks import log_prob, sample
from train.algorithm.rollout import final_values
from train.algorithm.state import Rollout, RunnerState, critic_input
from train.algorithm.trainer import Trainer

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "train/configs/doorway.yaml"
NETWORKS = {  # --network: the overrides of the main job's network section
    "mlp": [],
    "gru": ["network.kind=gru"],
    "lstm": ["network.others_encoder=lstm"],
}


# ----------------------------------------------------------------------------- measuring
def lane(fn: Callable) -> Callable:
    """``fn`` as a one-seed run compiles it: a ``vmap`` over a leading lane axis of one (the
    whole update of a single lane is one ``vmap``: ``Trainer.update_lanes``)."""
    def run(*args: Any) -> Any:
        out = jax.vmap(fn)(*jax.tree.map(lambda x: x[None], args))
        return jax.tree.map(lambda x: x[0], out)

    return run


def compiled_cost(fn: Callable, *args: Any) -> tuple[Any, float]:
    """``jit(fn)`` compiled for ``args`` (``compile_measured``) and its FLOPs by XLA's cost
    analysis (a loop's body counted once)."""
    compiled, _, _ = compile_measured(jax.jit(fn).lower(*args))
    cost = compiled.cost_analysis()
    if isinstance(cost, list):
        cost = cost[0] if cost else {}
    return compiled, float((cost or {}).get("flops", 0.0))


def best_seconds(compiled: Any, *args: Any, repeats: int = 3) -> float:
    """Best wall time (s) of ``repeats`` calls of a compiled function, after a warm-up call."""
    jax.block_until_ready(compiled(*args))
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(*args))
        best = min(best, time.perf_counter() - t0)
    return best


def timed(fn: Callable, *args: Any, repeats: int = 3) -> tuple[float, float]:
    """``(seconds, flops)`` of one call of ``fn(*args)`` compiled alone."""
    compiled, flops = compiled_cost(fn, *args)
    return best_seconds(compiled, *args, repeats=repeats), flops


# ----------------------------------------------------------------------------- peaks
def matmul_peak(n: int = 1024) -> float:
    """FLOP/s of a jitted ``[n, n] @ [n, n]`` float32 product (best of 10 calls)."""
    a, b = jax.random.normal(jax.random.PRNGKey(0), (2, n, n), jnp.float32)
    compiled, flops = compiled_cost(jnp.matmul, a, b)
    flops = flops if flops > 0 else 2.0 * n ** 3  # a GPU's cost analysis may not count it
    return flops / best_seconds(compiled, a, b, repeats=10)


def mlp_peak(rows: int, inputs: int, hidden: tuple[int, ...], heads: tuple[int, ...]
             ) -> float:
    """FLOP/s of the gradient (forward and backward pass) of plain ``tanh`` MLP towers, one
    per head size in ``heads``, ``inputs -> hidden... -> head``, on ``rows`` input rows
    (the faster of the plain layout and a lane of one)."""
    key = jax.random.PRNGKey(1)
    towers = []
    for head in heads:
        sizes = (inputs, *hidden, head)
        layers = []
        for fan_in, fan_out in zip(sizes[:-1], sizes[1:], strict=True):
            key, k = jax.random.split(key)
            layers.append((jax.random.normal(k, (fan_in, fan_out)) / np.sqrt(fan_in),
                           jnp.zeros(fan_out)))
        towers.append(layers)
    x = jax.random.normal(key, (rows, inputs))

    def loss(towers: list, x: jax.Array) -> jax.Array:
        total = 0.0
        for layers in towers:
            h = x
            for w, b in layers[:-1]:
                h = jnp.tanh(h @ w + b)
            w, b = layers[-1]
            total = total + jnp.sum(jnp.square(h @ w + b))
        return total

    # the better of the plain layout and a lane of one (docs/xla-cpu-learning-layout.md)
    rates = []
    for fn in (jax.grad(loss), lane(jax.grad(loss))):
        seconds, flops = timed(fn, towers, x, repeats=5)
        rates.append(flops / seconds)
    return max(rates)


# ----------------------------------------------------------------------------- phases
class Phases:
    """The phases of one update of ``trainer``, each compiled alone on the data of a real
    rollout (``runner``: one lane, after some updates; ``rollout``: its next one)."""

    def __init__(self, trainer: Trainer, runner: RunnerState, rollout: Rollout):
        self.trainer, self.runner, self.rollout = trainer, runner, rollout
        a = trainer.config.algorithm
        self.steps, self.epochs, self.minibatches = a.num_steps, a.update_epochs, \
            a.num_minibatches
        self.rows: dict[str, tuple[float, float]] = {}  # name -> (s, FLOPs) per update

    def add(self, name: str, seconds: float, flops: float) -> None:
        self.rows[name] = (seconds, flops)

    def environment(self) -> tuple[jax.Array, jax.Array, jax.Array]:
        """``num_steps`` environment steps (a scan, the rollout's actions); returns the raw
        observations and final observations ``[T, E, R, D]`` and the truncation flags ``[T, E,
        R]`` for the policy and normalisation phases."""
        t, batch = self.trainer, self.trainer.batch
        traj = self.rollout.traj
        shape = (self.steps, t.num_envs, t.slots)
        actions = (traj.action.reshape(shape) if batch.discrete
                   else jnp.clip(traj.action, -1.0, 1.0).reshape(shape + (-1,)))
        keys = jax.random.split(jax.random.PRNGKey(2), self.steps)
        count = t.num_agents_at(self.runner.steps)

        def run(states: tuple, actions: jax.Array, keys: jax.Array) -> tuple:
            def body(states: tuple, x: tuple) -> tuple:
                obs, states, _, _, trunc, info = batch.step(x[1], states, x[0], count)
                return states, (obs, info["final_observation"], trunc)
            return jax.lax.scan(body, states, (actions, keys))

        fn = lane(run)
        seconds, flops = timed(fn, self.runner.env_states, actions, keys)
        self.add(f"environment step (x{self.steps})", seconds, flops * self.steps)
        _, (obs, final, truncated) = jax.jit(fn)(self.runner.env_states, actions, keys)
        return obs, final, truncated

    def policy(self, final: jax.Array, truncated: jax.Array) -> None:
        """The rollout's network work: per step the actor and critic on the batch, sampling,
        log-probabilities, and the critic on the final observations ``final [T, E, R, D]`` of
        the environments with a truncated robot (``truncated [T, E, R]``)."""
        t, traj = self.trainer, self.rollout.traj
        discrete = t.batch.discrete
        keys = jax.random.split(jax.random.PRNGKey(3), self.steps)

        def run(params: Any, carry: tuple, obs_stats: Any, mask: jax.Array, xs: tuple
                ) -> tuple:
            def body(carry: tuple, x: tuple) -> tuple:
                actor_in, critic_in, starts, key, final, truncated = x
                carry, out, value = t.network.apply(params, carry, actor_in[None],
                                                    critic_in[None], starts[None])
                log_std = head_log_std(params, discrete)
                action = sample(key, out[0], log_std, discrete)
                logp = log_prob(out[0], log_std, action, discrete)
                final = final_values(t.rollout_parts, params, carry, obs_stats, final, mask,
                                     truncated)
                return carry, (action, logp, value[0], final)
            return jax.lax.scan(body, carry, xs)

        xs = (traj.actor_in, critic_input(traj), traj.starts, keys, final, truncated)
        seconds, flops = timed(lane(run), self.runner.params, self.rollout.memory,
                               self.runner.obs_stats, self.runner.obs_mask, xs)
        self.add(f"policy forward (x{self.steps})", seconds, flops * self.steps)

    def normalisation(self, obs: jax.Array) -> None:
        """Per step: the observation statistics' update, the actor's and critic's inputs of
        the observations, the return statistics and scaling (the final observations' inputs
        are the policy phase's, for the truncating environments alone)."""
        t, a = self.trainer, self.trainer.config.algorithm
        traj = self.rollout.traj
        shape = (self.steps, t.num_envs, t.slots)
        size = t.batch.obs_size

        def run(runner: RunnerState, xs: tuple) -> tuple:
            def body(carry: tuple, x: tuple) -> tuple:
                obs_stats, return_stats, returns = carry
                obs, active, reward = x
                obs_stats = obs_stats.update(obs.reshape(-1, size), active.reshape(-1))
                inputs = t.inputs(obs_stats, obs)
                returns = returns * a.gamma + reward
                return_stats = return_stats.update(returns.reshape(-1, 1), active.reshape(-1))
                scaled = return_stats.scale(reward, a.reward_clip)
                returns = jnp.where(active, returns, 0.0)
                return (obs_stats, return_stats, returns), (inputs, scaled)
            return jax.lax.scan(body, (runner.obs_stats, runner.return_stats, runner.returns),
                                xs)

        xs = (obs, traj.active.reshape(shape), traj.reward.reshape(shape))
        seconds, flops = timed(lane(run), self.runner, xs)
        self.add(f"obs/return normalisation (x{self.steps})", seconds, flops * self.steps)

    def gae(self) -> None:
        traj, settings = self.rollout.traj, self.trainer.settings

        def advantages(traj: Any, last_value: jax.Array) -> tuple:
            return gae(traj, last_value, settings.read(None, "gamma"),
                       settings.read(None, "gamma_lambda"))

        seconds, flops = timed(lane(advantages), traj, traj.value[-1])
        self.add("GAE", seconds, flops * self.steps)

    def _row_flops(self, trainer: Trainer) -> float:
        """FLOPs of one masked minibatch gradient, counted on its rows as one-step sequences
        (the same work for an MLP; a GRU's scan body would otherwise count once)."""
        order = jnp.arange(trainer.num_agents)
        memory, sub, adv, target = jax.tree.map(
            lambda x: x[0], trainer.learner.masked_batches(order, self.rollout))
        flat = lambda x: x.reshape((1, -1) + x.shape[2:])  # noqa: E731
        rows = adv.size
        memory = jax.tree.map(lambda c: jnp.zeros((rows,) + c.shape[1:], c.dtype), memory)
        grad = jax.value_and_grad(trainer.learner.loss, has_aux=True)
        _, flops = compiled_cost(lane(grad), self.runner.params, memory,
                                 jax.tree.map(flat, sub), flat(adv), flat(target))
        return flops

    def learning(self, masked: Trainer, compact: Trainer) -> dict[str, float]:
        """The minibatch gradients (one epoch's, as a scan; x epochs), the shuffle and gather,
        masked and compact, and the optimiser steps. Returns the shares of the compact
        minibatches' units that can learn and that were computed (whole and half chunks; the
        compact path gathers each chunk's data inside its gradient loop)."""
        params, opt_state = self.runner.params, self.runner.opt_state
        per_minibatch = self._row_flops(masked)
        order = jax.random.permutation(jax.random.PRNGKey(4), masked.num_agents)
        updates = self.epochs * self.minibatches
        out = {}
        for trainer, name in ((masked, "masked"), (compact, "compact")):
            if name == "masked":
                cut, grad = trainer.learner.masked_batches, jax.value_and_grad(trainer.learner.loss,
                                                                        has_aux=True)
                each = lambda p, b, g=grad: g(p, *b)  # noqa: E731
                share = 1.0
            else:
                cut = trainer.learner.compact_batches
                each = lambda p, b, t=trainer: t.learner.compact_grads(p, b, self.rollout)  # noqa: E731
            seconds, flops = timed(lane(cut), order, self.rollout, repeats=2)
            what = "shuffle + gather" if name == "masked" else "shuffle"
            self.add(f"{what}, {name} (x{self.epochs})", seconds * self.epochs,
                     flops * self.epochs)
            batches = jax.jit(lane(cut))(order, self.rollout)
            if name == "compact":
                units, counts = batches[0].shape[-1], np.asarray(batches[1])
                chunk, half = compact_chunks(units)
                whole, tails = compact_trips(counts, chunk, half)
                run = whole * chunk + tails * half
                share = float(np.sum(run) / (units * len(run)))
                out["computed"] = share
                out["active"] = float(np.sum(counts) / (units * len(run)))

            def epoch(params: Any, batches: tuple, each: Callable = each) -> Any:
                return jax.lax.scan(lambda c, b: (c, each(params, b)), 0, batches)[1]

            compiled, _ = compiled_cost(lane(epoch), params, batches)
            seconds = best_seconds(compiled, params, batches, repeats=2)
            self.add(f"minibatch gradients, {name} (x{updates})", seconds * self.epochs,
                     per_minibatch * share * updates)
        grads = jax.tree.map(lambda p: 1e-3 * jnp.ones_like(p), params)

        def steps(params: Any, opt_state: Any) -> tuple:
            def body(_: Any, carry: tuple) -> tuple:
                params, opt_state = carry
                change, opt_state = masked.optimizer.update(grads, opt_state, params)
                return jax.tree.map(jnp.add, params, change), opt_state
            return jax.lax.fori_loop(0, updates, body, (params, opt_state))

        seconds, flops = timed(lane(steps), params, opt_state)
        self.add(f"optimiser (x{updates})", seconds, flops * updates)
        return out


# ----------------------------------------------------------------------------- updates
def trainer_for(config: TrainConfig, compact: bool) -> Trainer:
    """A trainer of ``config`` with ``algorithm.compact`` set."""
    algorithm = dataclasses.replace(config.algorithm, compact=compact)
    return Trainer(dataclasses.replace(config, algorithm=algorithm))


def time_updates(trainer: Trainer, runner: RunnerState, count: int
                 ) -> tuple[float, float, RunnerState]:
    """Seconds per update of ``count`` updates of one lane (best of two calls after a warm-up,
    as the command line compiles them: ``update_chunk_lanes``), the host's work per call
    (dispatch, and fetching the logs once computed) and the runner after."""
    chunk = trainer.jitted_chunk_lanes(count)
    compiled, _, _ = compile_measured(chunk.lower(runner))
    runner, logs = compiled(runner)
    jax.block_until_ready(logs)
    best, host = math.inf, math.inf
    for _ in range(2):
        t0 = time.perf_counter()
        runner, logs = compiled(runner)
        dispatched = time.perf_counter() - t0
        jax.block_until_ready(logs)
        total = time.perf_counter() - t0
        t1 = time.perf_counter()
        jax.device_get(logs)
        host = min(host, dispatched + time.perf_counter() - t1)
        best = min(best, total)
    return best / count, host, runner


def report(name: str, config: TrainConfig, updates: int, peaks: tuple[float, float]) -> None:
    masked, compact = trainer_for(config, False), trainer_for(config, True)
    a = config.algorithm
    runners = jax.jit(jax.vmap(masked.init))(jax.random.PRNGKey(0)[None])
    off, host, runners = time_updates(masked, runners, updates)
    on, _, runners = time_updates(compact, runners, updates)
    runner = jax.tree.map(lambda x: x[0], runners)
    _, rollout, _ = jax.jit(lane(masked.collect))(runner)
    phases = Phases(masked, runner, rollout)
    obs, final, truncated = phases.environment()
    phases.policy(final, truncated)
    phases.normalisation(obs)
    phases.gae()
    learn = phases.learning(masked, compact)
    rows = masked.num_agents * a.num_steps // a.num_minibatches
    agent_steps = a.num_envs * a.num_steps * masked.slots
    active = float(jnp.mean(rollout.traj.active))
    print(f"\n{name}: IPPO {config.network.kind}/{config.network.others_encoder}, "
          f"{a.num_envs} envs x {masked.slots} slots x {a.num_steps} steps, {a.update_epochs} "
          f"epochs x {a.num_minibatches} minibatches of {rows:,} rows; active share of the "
          f"rollout {active:.2f}")
    print(f"{'phase':<44}{'s/update':>9}{'share':>7}{'GFLOP':>8}{'GFLOP/s':>9}"
          f"{'% matmul':>9}{'% MLP':>7}")

    def line(label: str, seconds: float, flops: float | None = None) -> None:
        text = f"{label:<44}{seconds:>9.3f}{seconds / off:>7.0%}"
        if flops is not None:
            rate = flops / seconds if seconds > 0 else 0.0
            text += (f"{flops / 1e9:>8.1f}{rate / 1e9:>9.1f}{rate / peaks[0]:>9.0%}"
                     f"{rate / peaks[1]:>7.0%}")
        print(text)

    for label, (seconds, flops) in phases.rows.items():
        line(label, seconds, flops)
    by_path = {path: {k: v for k, v in phases.rows.items() if other not in k}
               for path, other in (("masked", "compact"), ("compact", "masked"))}
    sums = {path: (sum(s for s, _ in rows.values()), sum(f for _, f in rows.values()))
            for path, rows in by_path.items()}
    learning = {path: sum(s for k, (s, _) in rows.items()
                          if k.startswith(("minibatch", "shuffle", "optimiser")))
                for path, rows in by_path.items()}
    line("rest of the update (scans, rewards, logs)", off - sums["masked"][0])
    line("whole update, compact off", off, sums["masked"][1])
    line("whole update, compact on", on, sums["compact"][1])
    per_chunk = max(1, min(a.num_updates, min(config.evaluation.every,
                                              config.logging.checkpoint_every,
                                              max(a.total_steps // 20, 1))
                           // a.steps_per_update))
    print(f"host work per call: {host * 1e3:.1f} ms (dispatch + fetching the logs), "
          f"{host / per_chunk * 1e3:.2f} ms per update in the command line's chunks of "
          f"{per_chunk}")
    print(f"learning phase (its phases summed): masked {learning['masked']:.3f} s, compact "
          f"{learning['compact']:.3f} s ({learning['masked'] / learning['compact']:.2f}x; "
          f"{learn['active']:.0%} of the units can learn, {learn['computed']:.0%} computed)")
    print(f"agent-steps/s (slots x envs x steps / s): compact off {agent_steps / off:,.0f}, "
          f"on {agent_steps / on:,.0f} ({off / on:.2f}x)")
    # The update's two halves as the update compiles them (the phases above are each compiled
    # alone, which can over- or understate a phase: the normalisation phase alone writes every
    # step's inputs to memory).
    rollout_s, _ = timed(lane(masked.collect), runner, repeats=2)
    halves = {name: timed(lane(t.learn_lane), runner.params, runner.opt_state, runner.key,
                          rollout, runner.hyper, repeats=2)[0]
              for t, name in ((masked, "masked"), (compact, "compact"))}
    print(f"as compiled in the update: rollout (steps, forward, normalisation, GAE) "
          f"{rollout_s:.3f} s; learning phase masked {halves['masked']:.3f} s, compact "
          f"{halves['compact']:.3f} s ({halves['masked'] / halves['compact']:.2f}x)", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--num-envs", type=int, default=None,
                        help="algorithm.num_envs (default: the config's, 256)")
    parser.add_argument("--robots", type=int, default=None,
                        help="robot slots and count (default: the config's, 5)")
    parser.add_argument("--network", nargs="+", default=list(NETWORKS), choices=list(NETWORKS))
    parser.add_argument("--updates", type=int, default=1, help="updates per timed call")
    parser.add_argument("--config", default=str(CONFIG))
    args = parser.parse_args()
    overrides = []
    if args.num_envs:
        overrides.append(f"algorithm.num_envs={args.num_envs}")
    if args.robots:
        overrides += [f"env.curriculum=[[0, {args.robots}]]",
                      f"env.min_agents={min(args.robots, 3)}"]
    config = load_config(args.config, overrides)
    a = config.algorithm
    probe = Trainer(config)
    rows = probe.num_agents * a.num_steps // a.num_minibatches
    width = probe.batch.obs_size + (probe.slots if config.network.agent_id else 0)
    print(f"jax {jax.__version__} on {jax.devices()[0].platform} ({jax.device_count()} "
          f"device(s)), {args.config}")
    peaks = matmul_peak(), mlp_peak(rows, width, config.network.hidden,
                                    (probe.actor.action_dim, 1))
    print(f"peaks: f32 matmul 1024^3 {peaks[0] / 1e9:.1f} GFLOP/s; MLP forward+backward "
          f"({rows:,} rows, {width} -> {list(config.network.hidden)} -> actor "
          f"{probe.actor.action_dim} + critic 1) {peaks[1] / 1e9:.1f} GFLOP/s")
    for name in args.network:
        report(name, load_config(args.config, overrides + NETWORKS[name]), args.updates,
               peaks)


if __name__ == "__main__":
    main()
