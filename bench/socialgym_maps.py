"""Import every SocialGym 2.0 map folder under a directory and drive robots on it under GO.

    python bench/socialgym_maps.py ../shared/sg2maps --robots 3 --episodes 8

For each folder: import it as ``sgjax.maps.import_socialgym`` does, with SocialGym's own scenario
for that map when it had one (``FOLDER_SCENARIOS``: the folders of ``../shared/sg2maps``; a
file name alone is ambiguous, exp1's and exp2's are both ``easy``), else one group per connected
part; then run ``--episodes`` episodes of ``--robots`` robots
(fewer where the map or its scenario cannot hold that many: the table says so) for the time limit,
every robot always GO over the local planner. Prints, per map: nodes and edges after the import,
how many robots arrived in each episode, and the smallest gap between a robot body and a wall
seen every tenth step (negative would mean a robot inside a wall).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import sgjax
from sgjax.environment.registry import robots_that_fit
from sgjax.maps.schema import point_segment_distances
from sgjax.maps.socialgym import import_socialgym

# The folders of ../shared/sg2maps whose map SocialGym ran with one of its own scenarios.
FOLDER_SCENARIOS = {
    "door": "envs_door", "hallway": "envs_hallway", "intersection": "envs_intersection",
    "round_about": "envs_round_about", "open": "envs_open", "multienv": "envs_multi",
    "closed_door_t1": "closed_door_1__same_goals", "closed_door_t2": "closed_door_1__same_goals",
    "exp1_train_easy": "exp1_train_scenario", "exp1_train_medium": "exp1_train_scenario",
    "exp1_train_hard": "exp1_train_scenario",
}


def drive(spec: sgjax.maps.MapSpec, robots: int, episodes: int) -> tuple[np.ndarray, float]:
    """Arrivals per episode ``[E]`` and the smallest body-wall gap (m) of a GO rollout."""
    env, params = sgjax.make(spec, num_agents=robots)
    keys = jax.random.split(jax.random.key(0), episodes)
    _, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    step = jax.jit(jax.vmap(env.step_env, in_axes=(0, 0, 0, None)))
    go = jnp.zeros((episodes, env.max_agents), jnp.int32)
    radius = np.asarray(params.robots.radius)
    gap = np.inf
    for t in range(int(params.max_steps)):
        _, state, *_ = step(keys, state, go, params)
        if t % 10 == 0 and len(spec.walls):
            xy = np.stack([np.asarray(state.robots.x), np.asarray(state.robots.y)], -1)
            clear = point_segment_distances(xy.reshape(-1, 2), spec.walls).min(axis=1)
            clear = clear.reshape(episodes, -1) - radius[None, :]
            live = np.asarray(state.robots.in_world)
            if live.any():
                gap = min(gap, float(clear[live].min()))
    return np.asarray(state.robots.succeeded).sum(axis=1), gap


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("root", type=Path, help="a folder of SocialGym map folders")
    parser.add_argument("--robots", type=int, default=3)
    parser.add_argument("--episodes", type=int, default=8)
    args = parser.parse_args()
    folders = sorted(p for p in args.root.iterdir() if p.is_dir())
    print(f"{'map':20s} {'scenario':26s} {'nodes':>5s} {'edges':>5s}  robots  arrived per "
          "episode              wall gap   seconds")
    for folder in folders:
        scenario = FOLDER_SCENARIOS.get(folder.name)
        t0 = time.perf_counter()
        try:
            spec = import_socialgym(folder, scenario=scenario)
            fit = robots_that_fit(spec)
            robots = min(args.robots, fit)
            arrived, gap = drive(spec, robots, args.episodes)
        except (ValueError, KeyError, FileNotFoundError) as err:
            print(f"{folder.name:20s} {scenario or '(one group per part)':26s} FAILED: {err}")
            continue
        note = "" if robots == args.robots else f" (holds {fit})"
        print(f"{folder.name:20s} {scenario or '(one group per part)':26s} "
              f"{spec.num_nodes:5d} {len(spec.edges):5d}  {robots:>2d}{note:10s} "
              f"{' '.join(str(int(a)) for a in arrived):28s} {gap:7.3f} m "
              f"{time.perf_counter() - t0:6.1f}")


if __name__ == "__main__":
    main()
