"""Every pedestrian model on every registered scenario: long random rollouts with 100
pedestrians, checked for NaN, walls and the speed cap; prints one row per (scenario, model).

    python bench/pedestrian_invariants.py [--steps 1500] [--humans 100] [--models ...]

Columns: NaN (any non-finite position, velocity or heading), the smallest clearance between a
pedestrian's body and a wall (m; negative = inside a wall), the largest speed over the cap
(m/s), the mean speed (m/s), and the seconds it took (compile included). 4 robots under random
GO/STOP (30% STOP), 2 environments.
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp

import sgjax
from sgjax.compilation_cache import fast_cpu_compile
from sgjax.kernels.geometry import point_segment_distance

MODELS = ("moussaid", "helbing", "orca", "hsfm")


def check(scenario: str, model: str, humans: int, steps: int, envs: int = 2) -> dict:
    env, params = sgjax.make(scenario, num_agents=4, num_humans=humans, human_model=model)
    _, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(jax.random.key(7), envs),
                                                      params)
    vstep = jax.vmap(env.step, in_axes=(0, 0, 0, None))
    m = params.map

    def body(st, k):
        k_act, k_step = jax.random.split(k)
        actions = (jax.random.uniform(k_act, (envs, 4)) < 0.3).astype(jnp.int32)
        st = vstep(jax.random.split(k_step, envs), st, actions, params)[1]
        h = st.humans
        speed = jnp.hypot(h.vx, h.vy)
        wall = point_segment_distance(h.x[..., None], h.y[..., None], m.wall_x1, m.wall_y1,
                                      m.wall_x2, m.wall_y2)
        clearance = jnp.min(jnp.where(m.wall_valid, wall, 99.0), axis=-1) - params.humans.radius
        finite = jnp.all(jnp.isfinite(h.x) & jnp.isfinite(h.vx) & jnp.isfinite(h.heading))
        cap = params.humans.max_speed_factor * h.desired_speed
        return st, (finite, jnp.min(jnp.where(h.active, clearance, 99.0)),
                    jnp.max(jnp.where(h.active, speed - cap, -99.0)),
                    jnp.mean(speed, where=h.active))

    t0 = time.perf_counter()
    _, (finite, clearance, over, speed) = jax.jit(lambda s: jax.lax.scan(
        body, s, jax.random.split(jax.random.key(8), steps)))(state)
    jax.block_until_ready(speed)
    return {"nan": not bool(jnp.all(finite)), "clearance": float(jnp.min(clearance)),
            "over_cap": float(jnp.max(over)), "speed": float(jnp.mean(speed)),
            "seconds": time.perf_counter() - t0}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=1500)
    parser.add_argument("--humans", type=int, default=100)
    parser.add_argument("--models", nargs="+", default=list(MODELS))
    parser.add_argument("--scenarios", nargs="+", default=None)
    args = parser.parse_args()
    fast_cpu_compile()
    scenarios = args.scenarios or sgjax.registered()
    print(f"jax {jax.__version__} on {jax.devices()[0].platform}: {args.humans} pedestrians, "
          f"4 robots, {args.steps} steps x 2 environments")
    print("| scenario | model | NaN | min wall clearance (m) | max over cap (m/s) | "
          "mean speed (m/s) | s |")
    print("|---|---|---|---|---|---|---|")
    bad = 0
    for scenario in scenarios:
        for model in args.models:
            r = check(scenario, model, args.humans, args.steps)
            bad += r["nan"] or r["clearance"] < -1e-4
            print(f"| {scenario} | {model} | {'yes' if r['nan'] else 'no'} | "
                  f"{r['clearance']:.4f} | {r['over_cap']:.1e} | {r['speed']:.2f} | "
                  f"{r['seconds']:.0f} |", flush=True)
    print(f"{bad} of {len(scenarios) * len(args.models)} runs with NaN or a body in a wall")


if __name__ == "__main__":
    main()
