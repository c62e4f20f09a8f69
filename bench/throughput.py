"""Throughput of sgjax's batched step against peer simulators, measured in one run.

Prints one table: agent-steps/s, env-steps/s, compile time and peak memory for each simulator,
action mode, robot count and number of environments. The whole step is timed (dynamics,
contacts, planner for GO/STOP, observations, rewards, auto-reset), run as
``jit(scan(env.step_batch))`` (``--resets vmap``: ``jit(scan(vmap(env.step)))``) with random
actions drawn inside the scan, from episodes whose clocks are staggered over the time limit so
that they end at a long rollout's steady rate.

Peers (skipped with a note when not installed): JaxMARL ``MPE_simple_spread_v3`` (pip jaxmarl)
with N agents and N landmarks, stepped the same way; VMAS ``navigation`` on the CPU (pip vmas,
after ``pip install torch==2.13.0``), stepped in its own batched torch loop.

Peak memory: for JAX, XLA's compiled memory analysis (arguments + outputs + temporaries) of the
timed function; for VMAS, the growth of the process's peak RSS (a coarse upper bound).

    python bench/throughput.py                      # the full table of the issue
    python bench/throughput.py --num-envs 64 1024 --robots 4 --peers none
    python bench/throughput.py --table pedestrians  # pedestrians {0,10,50,100} x envs {64,1024}
    python bench/throughput.py --table pedestrians --human-models moussaid helbing orca hsfm
    python bench/throughput.py --table robots --robots 10 --peers jaxmarl --rounds 3

The robots table compiles every row first and then times them all in turn; ``--rounds N`` does
that N times and keeps each row's best: on a shared machine a burst of load then slows every
row alike, instead of whichever happened to run during it. The load average is printed at the
start and the end.

Pedestrian table: pedestrian-steps/s of the whole sgjax step on the hallway (4 robots), beside
PySocialForce (pip pysocialforce) stepping one scene of as many pedestrians in the same walls.
"""

from __future__ import annotations

import argparse
import itertools
import os
import resource
import time
from collections.abc import Callable

import jax
import jax.numpy as jnp
from compiled import compile_measured

import sgjax
from sgjax.environment.presets import REWARD_PRESETS

DEFAULT_ENVS = (1, 64, 1024, 4096, 16384)
DEFAULT_ROBOTS = (4, 10)


def _scan_rollout(step_fn: Callable, sample_fn: Callable, steps: int) -> Callable:
    def rollout(state, key):
        def body(carry, k):
            k_act, k_step = jax.random.split(k)
            return step_fn(k_step, carry, sample_fn(k_act)), None

        state, _ = jax.lax.scan(body, state, jax.random.split(key, steps))
        return state

    return jax.jit(rollout)


# A prepared benchmark: (compile or set-up seconds, peak bytes, timer); ``timer(repeats)`` runs
# the timed rollout ``repeats`` times and returns the best seconds per step.
Prepared = tuple[float, int, Callable[[int], float]]


def _prepare_jax(rollout: Callable, state, steps: int) -> Prepared:
    """Compile ``rollout`` (``steps`` steps per call) and warm it up."""
    key = jax.random.key(1)
    compiled, compile_s, peak = compile_measured(rollout.lower(state, key))
    jax.block_until_ready(compiled(state, key))  # warm-up
    seeds = itertools.count(2)

    def timer(repeats: int) -> float:
        best = float("inf")
        for _ in range(repeats):
            t0 = time.perf_counter()
            jax.block_until_ready(compiled(state, jax.random.key(next(seeds))))
            best = min(best, time.perf_counter() - t0)
        return best / steps

    return compile_s, peak, timer


def bench_sgjax(mode: str, robots: int, num_envs: int, steps: int, scenario: str,
                humans: int = 0, terms: str = "default", human_model: str = "moussaid",
                batched_reset: bool = True) -> Prepared:
    """``terms``: an observation preset; its reward preset too when one has that name.
    ``batched_reset``: step with ``env.step_batch`` (new episodes sampled for the ended
    environments alone), else with ``jax.vmap(env.step)`` (sampled for all, kept where ended)."""
    rewards = terms if terms in REWARD_PRESETS else "default"
    env, params = sgjax.make(scenario, num_agents=robots, action_mode=mode, num_humans=humans,
                             observation_preset=terms, reward_preset=rewards,
                             human_model=human_model)
    state = staggered_states(env, params, num_envs)
    vstep = (env.step_batch if batched_reset
             else jax.vmap(env.step, in_axes=(0, 0, 0, None)))

    def step_fn(key, st, actions):
        return vstep(jax.random.split(key, num_envs), st, actions, params)[1]

    if mode == "go_stop":
        def sample(k):  # mostly GO, like a policy that sometimes yields
            return (jax.random.uniform(k, (num_envs, robots)) < 0.2).astype(jnp.int32)
    else:
        dim = env.config.action_dim

        def sample(k):
            return jax.random.uniform(k, (num_envs, robots, dim), minval=-1.0, maxval=1.0)

    return _prepare_jax(_scan_rollout(step_fn, sample, steps), state, steps)


def bench_jaxmarl(robots: int, num_envs: int, steps: int) -> Prepared:
    from jaxmarl import make as jaxmarl_make

    env = jaxmarl_make("MPE_simple_spread_v3", num_agents=robots, num_landmarks=robots)
    keys = jax.random.split(jax.random.key(0), num_envs)
    _, state = jax.vmap(env.reset)(keys)
    agents = env.agents
    num_actions = env.action_space(agents[0]).n
    vstep = jax.vmap(env.step)

    def step_fn(key, st, actions):
        acts = {a: actions[:, i] for i, a in enumerate(agents)}
        return vstep(jax.random.split(key, num_envs), st, acts)[1]

    def sample(k):
        return jax.random.randint(k, (num_envs, robots), 0, num_actions)

    return _prepare_jax(_scan_rollout(step_fn, sample, steps), state, steps)


def bench_vmas(robots: int, num_envs: int, steps: int) -> Prepared:
    import torch
    import vmas

    torch.set_num_threads(max(1, torch.get_num_threads()))
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter()
    env = vmas.make_env("navigation", num_envs=num_envs, device="cpu", continuous_actions=True,
                        n_agents=robots, seed=0)
    env.reset()
    setup_s = time.perf_counter() - t0

    def run(n: int) -> float:
        t = time.perf_counter()
        for _ in range(n):
            actions = [torch.rand(num_envs, 2) * 2.0 - 1.0 for _ in range(robots)]
            _, _, dones, _ = env.step(actions)
            if bool(dones.any()):
                for i in torch.nonzero(dones).flatten().tolist():
                    env.reset_at(i)
        return time.perf_counter() - t

    run(2)
    rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return setup_s, max(0, rss1 - rss0) * 1024, lambda repeats: min(
        run(steps) for _ in range(repeats)) / steps


def staggered_states(env, params, num_envs: int):
    """``num_envs`` reset states at clocks uniform over the time limit: episodes end at a long
    rollout's steady rate (``num_envs`` / limit per step, more where robots finish early)
    instead of all at once, or never within the timed steps."""
    keys = jax.random.split(jax.random.key(0), num_envs)
    # jitted: run eagerly, the reset's primitives would each be compiled and dispatched on
    # their own (minutes on a GPU before the first timed step)
    _, state = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, params)
    clocks = jax.random.randint(jax.random.key(2), (num_envs,), 0, params.max_steps)
    return state.replace(time=clocks.astype(state.time.dtype))


def pysocialforce_seconds(state, obstacles, steps: int, repeats: int) -> float:
    """PySocialForce's best seconds per 0.1 s step from ``state`` ``[N, 6]`` (position,
    velocity, goal) among ``obstacles`` (``[x1, x2, y1, y2]`` each), groups off."""
    import logging
    import tempfile
    from pathlib import Path

    import pysocialforce
    import toml

    logging.disable(logging.CRITICAL)  # it switches the root logger to DEBUG
    config = toml.load(Path(pysocialforce.__file__).parent / "config" / "default.toml")
    config["scene"]["enable_group"] = False
    config["step_width"] = 0.1  # read from the top level, not [scene]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "psf.toml"
        path.write_text(toml.dumps(config))
        sim = pysocialforce.Simulator(state, groups=None, obstacles=obstacles,
                                      config_file=str(path))
    sim.step(2)
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        sim.step(steps)
        best = min(best, (time.perf_counter() - t0) / steps)
    return best


def bench_pysocialforce(humans: int, steps: int, repeats: int) -> float:
    """PySocialForce's seconds per step for one scene of ``humans`` pedestrians in the hallway's
    walls (groups off, 0.1 s step), half starting in each room and heading for the other."""
    import numpy as np

    spec = sgjax.maps.load("hallway")
    obstacles = [[x1, x2, y1, y2] for x1, y1, x2, y2 in spec.walls]
    rng = np.random.default_rng(0)
    left = humans // 2
    x = np.concatenate([rng.uniform(-11, -4, left), rng.uniform(4, 11, humans - left)])
    y = rng.uniform(-5, 5, humans)
    speed = np.clip(rng.normal(1.34, 0.26, humans), 0.5, 2.0)
    state = np.stack([x, y, -np.sign(x) * speed, np.zeros(humans), -x, y], axis=-1)
    return pysocialforce_seconds(state, obstacles, steps, repeats)


def bench_rvo2(humans: int, steps: int, repeats: int) -> float:
    """RVO2's (pyrvo) seconds per step for one scene of ``humans`` ORCA agents crossing between
    the hallway's two rooms (no walls: RVO2 would need them as polygons), CrowdNav's settings
    (time horizons 5 s, 10 neighbours within 10 m, radius 0.25 m, 0.1 s step)."""
    import numpy as np
    import pyrvo

    rng = np.random.default_rng(0)
    left = humans // 2
    x = np.concatenate([rng.uniform(-11, -4, left), rng.uniform(4, 11, humans - left)])
    y = rng.uniform(-5, 5, humans)
    sim = pyrvo.RVOSimulator()
    sim.set_time_step(0.1)
    sim.set_agent_defaults(10.0, 10, 5.0, 5.0, 0.25, 1.3)
    for i in range(humans):
        sim.add_agent((float(x[i]), float(y[i])))
        sim.set_agent_pref_velocity(i, (float(-np.sign(x[i]) * 1.3), 0.0))
    sim.do_step()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(steps):
            sim.do_step()
        best = min(best, (time.perf_counter() - t0) / steps)
    return best


def pedestrian_table(humans_list, envs_list, robots: int, budget: int, repeats: int,
                     models=("moussaid",)) -> None:
    """Pedestrian-steps/s of sgjax (whole environment step: robots, planner, contacts,
    pedestrians, auto-reset) for each pedestrian model, against PySocialForce's single scene
    and RVO2's (ORCA), in the same run."""
    print(f"\npedestrians on the hallway ({robots} robots, GO/STOP, dt 0.1 s)")
    header = (f"{'simulator':<24}{'peds':>6}{'envs':>7}{'ped-steps/s':>14}{'env-steps/s':>13}"
              f"{'compile s':>11}{'peak MB':>9}")
    print(header)
    print("-" * len(header))
    ours: dict[tuple[str, int], float] = {}
    theirs: dict[tuple[str, int], float] = {}
    for humans in humans_list:
        for model in models:
            for envs in envs_list:
                steps = int(max(10, min(200, budget // max(1, envs * max(humans, robots)))))
                compile_s, peak, timer = bench_sgjax("go_stop", robots, envs, steps, "hallway",
                                                     humans, human_model=model)
                per_step = timer(repeats)
                rate = envs * humans / per_step
                ours[model, humans] = max(ours.get((model, humans), 0.0), rate)
                print(f"{'sgjax ' + model:<24}{humans:>6}{envs:>7}{rate:>14,.0f}"
                      f"{envs / per_step:>13,.0f}{compile_s:>11.2f}{peak / 2**20:>9.1f}",
                      flush=True)
            if not humans:
                break  # no pedestrians: the model does not matter
        if not humans:
            continue
        for peer, run in (("pysocialforce", bench_pysocialforce), ("rvo2", bench_rvo2)):
            try:
                per_step = run(humans, 30, repeats)
            except ImportError as err:
                print(f"{peer}: skipped ({err})")
                continue
            theirs[peer, humans] = humans / per_step
            print(f"{peer + ' (1 scene)':<24}{humans:>6}{1:>7}{humans / per_step:>14,.0f}"
                  f"{1 / per_step:>13,.0f}{'':>11}{'':>9}", flush=True)
    pairs = {"pysocialforce": ("moussaid", "helbing", "hsfm"), "rvo2": ("orca",)}
    for (peer, humans), rate in sorted(theirs.items()):
        for model in pairs[peer]:
            if (model, humans) in ours:
                ratio = ours[model, humans] / rate
                shown = f"{ratio:,.0f}" if ratio >= 10 else f"{ratio:.2f}"
                print(f"  {humans:>4} pedestrians: sgjax {model} {shown}x {peer} per "
                      "pedestrian-step")


def _steps_for(num_envs: int, robots: int, budget: int) -> int:
    return int(max(10, min(200, budget // max(1, num_envs * robots))))


def _prepare_row(args, robots: int, envs: int, steps: int) -> list[tuple[str, Prepared]]:
    """Every simulator of one robot count and batch size, compiled and warmed up."""
    prepared = []
    for terms in args.terms:
        for mode in args.modes:
            for resets in args.resets:
                name = (f"sgjax {mode}" + ("" if terms == "default" else f" [{terms}]")
                        + ("" if resets == "batched" else " [vmap(step)]"))
                prepared.append((name, bench_sgjax(mode, robots, envs, steps, args.scenario,
                                                   terms=terms,
                                                   batched_reset=resets == "batched")))
    for peer in args.peers:
        try:
            if peer == "jaxmarl":
                prepared.append(("jaxmarl simple_spread_v3", bench_jaxmarl(robots, envs, steps)))
            elif peer == "vmas":
                prepared.append(("vmas navigation (torch cpu)",
                                 bench_vmas(robots, envs, max(5, min(steps, 50)))))
        except ImportError as err:
            print(f"{peer}: skipped ({err})")
    return prepared


def _load() -> str:
    return "load average " + " ".join(f"{v:.2f}" for v in os.getloadavg())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--num-envs", type=int, nargs="+", default=list(DEFAULT_ENVS))
    parser.add_argument("--robots", type=int, nargs="+", default=list(DEFAULT_ROBOTS))
    parser.add_argument("--modes", nargs="+", default=["go_stop", "continuous"])
    parser.add_argument("--peers", nargs="+", default=["jaxmarl", "vmas"],
                        help="peer simulators to run: jaxmarl, vmas, or none")
    parser.add_argument("--scenario", default="doorway")
    parser.add_argument("--budget", type=int, default=4_000_000,
                        help="agent-steps per timed repeat (sets the scan length)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=1,
                        help="time every row of the robots table in this many rounds (of "
                             "--repeats each, all rows in turn) and keep each row's best")
    parser.add_argument("--table", choices=["robots", "pedestrians", "all"], default="all",
                        help="which table to run: robots against JaxMARL/VMAS, pedestrians "
                             "against PySocialForce, or both")
    parser.add_argument("--pedestrians", type=int, nargs="+", default=[0, 10, 50, 100])
    parser.add_argument("--pedestrian-envs", type=int, nargs="+", default=[64, 1024])
    parser.add_argument("--human-models", nargs="+", default=["moussaid"],
                        help="pedestrian models to time: moussaid helbing orca hsfm")
    parser.add_argument("--terms", nargs="+", default=["default"],
                        help="observation/reward presets to time (docs/terms.md), e.g. "
                             "default socialgym enforced_order")
    parser.add_argument("--resets", nargs="+", choices=["batched", "vmap"],
                        default=["batched"],
                        help="how sgjax's auto-reset is stepped: batched (env.step_batch, new "
                             "episodes sampled for the ended environments alone) and/or vmap "
                             "(jax.vmap(env.step): sampled for every environment each step)")
    args = parser.parse_args()

    print(f"jax {jax.__version__} on {jax.devices()[0].platform} "
          f"({len(jax.devices())} device(s)); scenario {args.scenario}; {_load()}")
    if args.table in ("pedestrians", "all"):
        pedestrian_table(args.pedestrians, args.pedestrian_envs, 4, args.budget, args.repeats,
                         args.human_models)
    if args.table == "pedestrians":
        print(_load())
        return
    header = (f"{'simulator':<36}{'robots':>7}{'envs':>8}{'agent-steps/s':>15}"
              f"{'env-steps/s':>13}{'compile s':>11}{'peak MB':>10}")
    print(header)
    print("-" * len(header))
    best: dict[tuple[str, int], float] = {}
    rows = [(robots, envs, name, prepared) for robots in args.robots for envs in args.num_envs
            for name, prepared in _prepare_row(args, robots, envs,
                                               _steps_for(envs, robots, args.budget))]
    per_step = [float("inf")] * len(rows)
    for _ in range(args.rounds):
        for i, (*_, (_, _, timer)) in enumerate(rows):
            per_step[i] = min(per_step[i], timer(args.repeats))
    for (robots, envs, name, (compile_s, peak, _)), seconds in zip(rows, per_step, strict=True):
        agent_sps = envs * robots / seconds
        best[(name, robots)] = max(best.get((name, robots), 0.0), agent_sps)
        print(f"{name:<36}{robots:>7}{envs:>8}{agent_sps:>15,.0f}{envs / seconds:>13,.0f}"
              f"{compile_s:>11.2f}{peak / 2**20:>10.1f}", flush=True)
    print("\nbest agent-steps/s over batch sizes, and ratio to each peer:")
    for (name, robots), sps in sorted(best.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        ratios = [f"{sps / best[(p, robots)]:.1f}x {p.split()[0]}"
                  for p in ("jaxmarl simple_spread_v3", "vmas navigation (torch cpu)")
                  if (p, robots) in best and not name.startswith(p.split()[0])]
        print(f"  {name:<36} {robots:>3} robots {sps:>14,.0f}   " + ", ".join(ratios))
    print(_load())


if __name__ == "__main__":
    main()
