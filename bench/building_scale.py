"""Cost against the number of walls: the whole sgjax step from a mini-game to a building floor.

Prints agent-steps/s, compile time and peak memory of ``jit(scan(env.step_batch))`` (4 robots,
mostly GO over the local planner, episodes at staggered clocks as in ``throughput.py``) on
maps of growing wall count: the shipped doorway and office, SocialGym 2.0's GDC floors
(``--sg2maps``: GDC1 1,374 walls, GDC2 3,914, GDC3 5,647). Each map runs twice: with the
contacts' wall broad phase as ``sgjax.make`` chooses it (``kernels.contacts.uses_broad_phase``:
the walls of the body's grid cell) and with every wall tested (the map's ``reach`` set to 0),
so the table shows what the broad phase buys and where the dense test is kept.

    python bench/building_scale.py
    python bench/building_scale.py --maps doorway GDC3 --envs 64 256 --rounds 3
    python bench/building_scale.py --maps GDC3 --humans 500 --human-range 3 --envs 4

With ``--observations transfer`` every robot also casts a 16-beam, 5 m lidar and sees the
others (the transfer preset): on a building floor its beams read the walls from the cell lists
along them (``sgjax.kernels.walls_along``), and the "every wall" row casts them at every wall.

With ``--humans N`` each environment also has N pedestrians (Moussaid, random goals) and
agent-steps count them; ``--human-range R`` gives them a neighbour range, so on a building
floor their wall terms read the map's wall grid too (``sgjax.humans.near_walls``), and the
"every wall" row tests every wall for them as well.

Every row is compiled first and then timed in turn, ``--rounds`` times, keeping each row's
best (a burst of load slows every row alike). The load average is printed at the start and
the end: time it on an idle machine.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import jax
import jax.numpy as jnp
from throughput import _prepare_jax as prepare_jax
from throughput import staggered_states

import sgjax
from sgjax.kernels.contacts import uses_broad_phase

SG2MAPS = Path(__file__).resolve().parents[2] / "shared" / "sg2maps"
SHIPPED = ("doorway", "hallway", "intersection", "roundabout", "open", "office")


def scenario(name: str, sg2maps: Path):
    """A shipped map's name, or SocialGym 2.0's map folder of that name, imported."""
    if name in SHIPPED:
        return name
    folder = sg2maps / name
    if not folder.is_dir():
        raise SystemExit(f"--maps {name}: not a shipped map and no folder {folder} "
                         "(give --sg2maps)")
    from sgjax.maps.socialgym import import_socialgym

    return import_socialgym(folder)


def prepare(env, params, robots: int, envs: int, steps: int):
    """``(compile s, peak bytes, timer)``: the compiled rollout of ``steps`` batched steps;
    ``timer(repeats)`` returns the best seconds per step."""
    state = staggered_states(env, params, envs)

    def rollout(state, key):
        def body(carry, k):
            state, seen = carry
            k_act, k_step = jax.random.split(k)
            stop = (jax.random.uniform(k_act, (envs, robots)) < 0.2).astype(jnp.int32)
            obs, state, *_ = env.step_batch(jax.random.split(k_step, envs), state, stop, params)
            # the observations are consumed, or XLA drops their terms (the lidar) unmeasured
            return (state, seen + jnp.sum(obs)), None

        return jax.lax.scan(body, (state, jnp.zeros(())), jax.random.split(key, steps))[0]

    return prepare_jax(jax.jit(rollout), state, steps)


def _load() -> str:
    return "load average " + " ".join(f"{v:.2f}" for v in os.getloadavg())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--maps", nargs="+", default=["doorway", "office", "GDC1", "GDC2", "GDC3"])
    parser.add_argument("--sg2maps", type=Path, default=SG2MAPS)
    parser.add_argument("--robots", type=int, default=4)
    parser.add_argument("--envs", type=int, nargs="+", default=[64])
    parser.add_argument("--steps", type=int, default=100, help="steps per timed rollout")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--humans", type=int, default=0, help="pedestrians per environment")
    parser.add_argument("--human-range", type=float, default=None,
                        help="the pedestrians' neighbour range (m)")
    parser.add_argument("--observations", default="default",
                        help="observation preset (transfer: a 16-beam lidar and the others)")
    args = parser.parse_args()
    print(f"jax {jax.__version__} on {jax.devices()[0].platform}, {os.cpu_count()} CPU(s); "
          f"{args.robots} robots, {args.humans} pedestrians (range {args.human_range}), "
          f"observations {args.observations}; "
          f"{_load()}", flush=True)
    rows = []
    for name in args.maps:
        crowd = (dict(num_humans=args.humans, human_range=args.human_range) if args.humans
                 else {})
        env, params = sgjax.make(scenario(name, args.sg2maps), num_agents=args.robots,
                                 observation_preset=args.observations, **crowd)
        m = params.map
        walls, listed = int(m.wall_valid.sum()), int(m.cell_walls.shape[1])
        paths = [("as chosen", params)]
        if uses_broad_phase(m):
            paths.append(("every wall", params.replace(map=m.replace(reach=0.0))))
        for label, p in paths:
            for envs in args.envs:
                path = ("broad phase" if uses_broad_phase(p.map) else "every wall") + (
                    "" if label == "as chosen" else " (forced)")
                rows.append((name, walls, listed, path, envs,
                             prepare(env, p, args.robots, envs, args.steps)))
                print(f"  compiled {name}, {path}, {envs} environments: "
                      f"{rows[-1][-1][0]:.1f} s", flush=True)
    per_step = [float("inf")] * len(rows)
    for _ in range(args.rounds):
        for i, row in enumerate(rows):
            per_step[i] = min(per_step[i], row[-1][2](args.repeats))
    header = (f"{'map':<10}{'walls':>7}{'per cell':>10}  {'contacts':<24}{'envs':>6}"
              f"{'agent-steps/s':>15}{'compile s':>11}{'peak MB':>9}")
    print(header + "\n" + "-" * len(header))
    for (name, walls, listed, path, envs, (compile_s, peak, _)), seconds in zip(
            rows, per_step, strict=True):
        print(f"{name:<10}{walls:>7}{listed:>10}  {path:<24}{envs:>6}"
              f"{envs * (args.robots + args.humans) / seconds:>15,.0f}{compile_s:>11.1f}"
              f"{peak / 2**20:>9.1f}")
    print(_load())


if __name__ == "__main__":
    main()
