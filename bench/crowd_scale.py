"""Cost against the size of the crowd: the whole sgjax step with 50 to 2,000 pedestrians, beside
JuPedSim and PySocialForce in the same run.

The scene is a 40 m square crossing (``sgjax.maps.crowd_scenarios.square_crossing``): people walk
between points on opposite sides, so the two flows cross in the middle; sgjax adds 4 robots
(mostly GO over the local planner, episodes at staggered clocks as in ``throughput.py``). Each
crowd runs as published (every body acts on every pedestrian) and with a neighbour range
(``human_range``: bodies beyond it do not act), found through cell lists
(``human_search="grid"``) or, as ``sgjax.make`` chooses by default, dense below
``humans.neighbors.GRID_FROM_HUMANS`` pedestrians. Peers, one scene on one core:

* JuPedSim 1.4 (``pip install jupedsim``): its social force model (Helbing, Farkas and Vicsek
  2000, the interaction sgjax's ``hsfm`` pedestrians share), 0.01 s iterations, agents walking
  to the far side of the same square;
* PySocialForce 1.1.2: the Moussaid 2009 law sgjax's ``moussaid`` pedestrians implement,
  0.1 s steps (all pairs in NumPy: only up to ``--psf-max`` pedestrians).

    python bench/crowd_scale.py
    python bench/crowd_scale.py --humans 1000 --models moussaid hsfm --rounds 3
    python bench/crowd_scale.py --envs-factor 64 --peers jupedsim    # on a GPU

agent-steps/s counts pedestrians and robots per environment step (sgjax: 0.1 s, the models'
own sub-steps inside; JuPedSim: one 0.01 s iteration; PySocialForce: one 0.1 s step), as the
issue's table does; the simulated seconds per wall second are printed beside it. Every sgjax
row is compiled first and then timed in turn, ``--rounds`` times, keeping each row's best.
Time it on an idle machine (the load average is printed).
"""

from __future__ import annotations

import argparse
import itertools
import os
import time

import jax
import jax.numpy as jnp
import numpy as np
from compiled import compile_measured
from throughput import pysocialforce_seconds, staggered_states

import sgjax
from sgjax.maps.crowd_scenarios import square_crossing

SIDE = 40.0  # m
# environments per crowd: about 4,000 pedestrians per batch, as the table
ENVS = {50: 64, 100: 40, 200: 16, 500: 6, 1000: 4, 2000: 2}


def sgjax_row(humans: int, envs: int, model: str, search: str | None, rng: float,
              robots: int, steps: int):
    """``(compile s, peak bytes, timer, overflow)`` of ``steps`` batched steps of the crossing;
    ``search`` ``None``: no range (every body)."""
    kw = {} if search is None else {"human_range": rng, "human_search": search}
    env, params = sgjax.make(square_crossing(side=SIDE), num_agents=robots, num_humans=humans,
                             human_goals="routes", human_model=model, **kw)
    state = staggered_states(env, params, envs)

    def rollout(state, key):
        def body(carry, k):
            k_act, k_step = jax.random.split(k)
            stop = (jax.random.uniform(k_act, (envs, robots)) < 0.2).astype(jnp.int32)
            out = env.step_batch(jax.random.split(k_step, envs), carry, stop, params)
            return out[1], jnp.max(out[5]["neighbor_overflow"])

        state, overflow = jax.lax.scan(body, state, jax.random.split(key, steps))
        return state, jnp.max(overflow)

    compiled, compile_s, peak = compile_measured(jax.jit(rollout).lower(state, jax.random.key(1)))
    overflow = int(compiled(state, jax.random.key(1))[1])  # and the warm-up
    seeds = itertools.count(2)

    def timer(repeats: int) -> float:
        best = float("inf")
        for _ in range(repeats):
            t0 = time.perf_counter()
            jax.block_until_ready(compiled(state, jax.random.key(next(seeds))))
            best = min(best, time.perf_counter() - t0)
        return best / steps

    return compile_s, peak, timer, overflow, env.config.humans.uses_grid


def crossing_starts(humans: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Start points ``[N, 2]`` and far-side goals ``[N, 2]`` (m) of a crossing on a ``SIDE``
    square: half walk west to east from ``x < 12``, half south to north from ``y < 12``, on a
    0.55 m lattice (the two start areas apart), so the flows cross in the square's middle."""
    rng = np.random.default_rng(seed)
    near = np.arange(0.5, 12.0, 0.55)  # m from the start side
    along = np.arange(12.5, SIDE - 0.4, 0.55)  # m along it, clear of the other start area
    lattice = np.stack(np.meshgrid(near, along), axis=-1).reshape(-1, 2)
    half = humans // 2
    if humans - half > len(lattice):
        raise SystemExit(f"--humans {humans}: at most {2 * len(lattice)} fit the start areas")
    west = lattice[rng.permutation(len(lattice))[:half]]
    south = lattice[rng.permutation(len(lattice))[:humans - half]][:, ::-1]
    starts = np.concatenate([west, south])
    goals = np.concatenate([np.stack([np.full(half, SIDE - 0.5), west[:, 1]], axis=1),
                            np.stack([south[:, 0], np.full(humans - half, SIDE - 0.5)], axis=1)])
    return starts, goals


def bench_jupedsim(humans: int, iterations: int, repeats: int) -> float:
    """JuPedSim's seconds per 0.01 s iteration of its social force model: ``humans`` agents
    crossing the square toward exits along the far sides (none arrives within the timing)."""
    import jupedsim as jps
    from shapely import Polygon

    square = Polygon([(0, 0), (SIDE, 0), (SIDE, SIDE), (0, SIDE)])
    sim = jps.Simulation(model=jps.SocialForceModel(), geometry=square, dt=0.01)
    east = sim.add_exit_stage([(SIDE - 0.5, 0.5), (SIDE - 0.1, 0.5), (SIDE - 0.1, SIDE - 0.5),
                               (SIDE - 0.5, SIDE - 0.5)])
    north = sim.add_exit_stage([(0.5, SIDE - 0.5), (SIDE - 0.5, SIDE - 0.5),
                                (SIDE - 0.5, SIDE - 0.1), (0.5, SIDE - 0.1)])
    starts, _ = crossing_starts(humans)
    speed = np.clip(np.random.default_rng(1).normal(1.34, 0.26, humans), 0.5, 2.0)
    for i, (x, y) in enumerate(starts):
        stage = east if i < humans // 2 else north
        journey = sim.add_journey(jps.JourneyDescription([stage]))
        sim.add_agent(jps.SocialForceModelAgentParameters(
            journey_id=journey, stage_id=stage, position=(float(x), float(y)),
            desired_speed=float(speed[i]), radius=0.25))
    for _ in range(5):
        sim.iterate()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(iterations):
            sim.iterate()
        best = min(best, (time.perf_counter() - t0) / iterations)
    if sim.agent_count() != humans:
        raise RuntimeError("JuPedSim: agents arrived during the timing; time fewer iterations")
    return best


def bench_pysocialforce(humans: int, steps: int, repeats: int) -> float:
    """PySocialForce's seconds per 0.1 s step: ``humans`` pedestrians crossing the square
    (its four sides as obstacles, groups off)."""
    starts, goals = crossing_starts(humans)
    heading = goals - starts
    heading /= np.linalg.norm(heading, axis=1, keepdims=True)
    speed = np.clip(np.random.default_rng(1).normal(1.34, 0.26, humans), 0.5, 2.0)
    state = np.concatenate([starts, heading * speed[:, None], goals], axis=1)
    obstacles = [[0, SIDE, 0, 0], [SIDE, SIDE, 0, SIDE], [0, SIDE, SIDE, SIDE], [0, 0, 0, SIDE]]
    return pysocialforce_seconds(state, obstacles, steps, repeats)


def _load() -> str:
    return "load average " + " ".join(f"{v:.2f}" for v in os.getloadavg())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--humans", type=int, nargs="+", default=[50, 200, 500, 1000, 2000])
    parser.add_argument("--models", nargs="+", default=["moussaid", "hsfm"])
    parser.add_argument("--range", type=float, default=3.0, dest="rng",
                        help="the neighbour range of the rows with one (m)")
    parser.add_argument("--robots", type=int, default=4)
    parser.add_argument("--steps", type=int, default=40, help="steps per timed rollout")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--peers", nargs="*", default=["jupedsim", "pysocialforce"])
    parser.add_argument("--envs-factor", type=int, default=1,
                        help="environments per crowd size times this (a GPU takes many more)")
    parser.add_argument("--psf-max", type=int, default=500,
                        help="largest crowd given to PySocialForce (all pairs in NumPy)")
    args = parser.parse_args()
    print(f"jax {jax.__version__} on {jax.devices()[0].platform}, {os.cpu_count()} CPU(s); "
          f"{args.robots} robots; {_load()}", flush=True)
    rows = []
    for humans in args.humans:
        envs = args.envs_factor * ENVS.get(humans, max(1, 4000 // humans))
        for model in args.models:
            for search in (None, "auto", "grid"):
                row = sgjax_row(humans, envs, model, search, args.rng, args.robots, args.steps)
                if search == "grid" and rows and rows[-1][3] == "auto" and rows[-1][-1][4]:
                    continue  # auto already took the lists
                label = ("every body" if search is None else
                         f"{args.rng:g} m, " + ("cell lists" if row[4] else "dense"))
                rows.append((humans, envs, model, search, label, row))
                print(f"  compiled {model}, {humans} pedestrians, {label}, {envs} environments: "
                      f"{row[0]:.1f} s", flush=True)
    per_step = [float("inf")] * len(rows)
    for _ in range(args.rounds):
        for i, row in enumerate(rows):
            per_step[i] = min(per_step[i], row[-1][2](args.repeats))
    peers = []
    for humans in args.humans:
        if "jupedsim" in args.peers:
            try:
                peers.append(("JuPedSim social force", humans, 0.01,
                              bench_jupedsim(humans, 100, args.repeats)))
            except ImportError as err:
                print(f"jupedsim: skipped ({err})")
        if "pysocialforce" in args.peers and humans <= args.psf_max:
            peers.append(("PySocialForce (Moussaid)", humans, 0.1,
                          bench_pysocialforce(humans, 5, args.repeats)))
    header = (f"{'simulator':<26}{'peds':>6}{'envs':>6}  {'pairs':<22}{'agent-steps/s':>15}"
              f"{'sim-s/s':>9}{'compile s':>11}{'peak MB':>9}{'overflow':>10}")
    print(header + "\n" + "-" * len(header))
    best: dict[int, float] = {}
    for (humans, envs, model, _, label, row), seconds in zip(rows, per_step, strict=True):
        compile_s, peak, _, overflow, _ = row
        rate = envs * (humans + args.robots) / seconds
        best[humans] = max(best.get(humans, 0.0), rate)
        print(f"{'sgjax ' + model:<26}{humans:>6}{envs:>6}  {label:<22}{rate:>15,.0f}"
              f"{envs * 0.1 / seconds:>9.1f}{compile_s:>11.1f}{peak / 2**20:>9.1f}"
              f"{overflow:>10}")
    for name, humans, dt, seconds in peers:
        print(f"{name:<26}{humans:>6}{1:>6}  {'(its own)':<22}{humans / seconds:>15,.0f}"
              f"{dt / seconds:>9.1f}{'':>11}{'':>9}{'':>10}")
    for name, humans, _, seconds in peers:
        if humans in best:
            ratio = best[humans] * seconds / humans
            print(f"  {humans:>5} pedestrians: sgjax's best row {ratio:.2f}x "
                  f"{name} per agent-step")
    print(_load())


if __name__ == "__main__":
    main()
