"""Long random rollouts of every world the simulator offers, checked for what must never happen.

Each case steps a batch of environments with random actions (continuous commands held for a
few steps at full magnitude, or random GO/STOP) through auto-resets until it has made
``--agent-steps`` robot-steps (robots only; pedestrians come on top), and prints per case:
non-finite values (robot and pedestrian positions and velocities), the worst wall overlap of a
robot and of a pedestrian (m: radius minus the distance to the nearest wall, after the step),
the worst robot-robot overlap (m, between active robots, after contact resolution), the robot
contacts seen (a rollout that never touched anything tests nothing) and the rate in
robot-steps per second, on this machine.

    python bench/stress.py --agent-steps 1e7            # every case, 10 million robot-steps
    python bench/stress.py --cases hsfm orca --agent-steps 1e6

Cases: every robot preset on its own (continuous, bang-bang), a mixed team, the GO/STOP
planner path, each pedestrian model (Moussaid and Helbing social forces, ORCA, HSFM) and
pedestrian groups among robots, and the generated crowd scenarios.
"""

from __future__ import annotations

import argparse
import math
import time

import jax
import jax.numpy as jnp
import numpy as np

import sgjax
from sgjax.evaluation.provenance import cpu_model
from sgjax.kernels.geometry import point_segment_distance

HOLD = 8  # steps a continuous command is held
CASES: dict[str, tuple[str, dict]] = {
    "socialgym": ("doorway", {"robots": "socialgym"}),
    "jackal": ("office", {"robots": "jackal"}),
    "turtlebot3": ("hallway", {"robots": "turtlebot3"}),
    "cobot": ("hallway", {"robots": "cobot"}),
    "automata": ("intersection", {"robots": "automata"}),
    "mixed team": ("roundabout", {"robots": ["socialgym", "cobot", "automata", "turtlebot3"]}),
    "go/stop planner": ("doorway", {"action_mode": "go_stop"}),
    "moussaid": ("hallway", {"num_humans": 8, "human_model": "moussaid"}),
    "helbing": ("hallway", {"num_humans": 8, "human_model": "helbing"}),
    "orca": ("intersection", {"num_humans": 8, "human_model": "orca"}),
    "hsfm": ("intersection", {"num_humans": 8, "human_model": "hsfm"}),
    "groups": ("open", {"num_humans": 8, "human_groups": [3, 3, 2]}),
    "circle_crossing": ("circle_crossing", {"num_humans": 10}),
    "square_crossing": ("square_crossing", {"num_humans": 10}),
    "parallel_traffic": ("parallel_traffic", {"num_humans": 10}),
    "perpendicular_traffic": ("perpendicular_traffic", {"num_humans": 10}),
}


def wall_overlap(x: jax.Array, y: jax.Array, radius: jax.Array, present: jax.Array,
                 m) -> jax.Array:
    """The worst ``radius - distance to the nearest wall`` (m) over present bodies."""
    d = point_segment_distance(x[..., None], y[..., None], m.wall_x1, m.wall_y1, m.wall_x2,
                               m.wall_y2)
    d = jnp.min(jnp.where(m.wall_valid, d, jnp.inf), axis=-1)
    return jnp.max(jnp.where(present, radius - d, -jnp.inf))


def stress(name: str, agent_steps: float, num_envs: int, chunk: int) -> dict:
    scenario, options = CASES[name]
    options = {"num_agents": 4, "action_mode": "continuous", "time_limit": 30.0, **options}
    env, params = sgjax.make(scenario, **options)
    robots, m = params.robots, params.map
    count = env.max_agents
    continuous = env.config.action_mode == "continuous"
    step = jax.vmap(env.step, in_axes=(0, 0, 0, None))

    def one(carry, t):
        state, key, worst = carry
        key, k_act, k_env = jax.random.split(key, 3)
        if continuous:
            held = jax.random.fold_in(jax.random.key(7), t // HOLD)
            actions = jnp.sign(jax.random.uniform(held, (num_envs, count,
                                                         env.config.action_dim), minval=-1))
        else:
            actions = jax.random.bernoulli(k_act, 0.7, (num_envs, count)).astype(jnp.int32)
        _, state, _, _, _, info = step(jax.random.split(k_env, num_envs), state, actions,
                                       params)
        after = info["final_robots"]  # before any auto-reset
        values = [after.x, after.y, after.kin.v_forward, after.kin.v_lateral, after.kin.omega]
        humans = state.humans
        if humans is not None and humans.x.shape[-1]:
            values += [humans.x, humans.y, humans.vx, humans.vy]
        bad = sum(jnp.sum(~jnp.isfinite(v)) for v in values)
        robot_wall = wall_overlap(after.x, after.y, robots.radius, after.present, m)
        human_wall = -jnp.inf
        if humans is not None and humans.x.shape[-1]:
            human_wall = wall_overlap(humans.x, humans.y, params.humans.radius, humans.active,
                                      m)
        gap = jnp.hypot(after.x[:, :, None] - after.x[:, None, :],
                        after.y[:, :, None] - after.y[:, None, :])
        pair = (after.active[:, :, None] & after.active[:, None, :]
                & ~jnp.eye(count, dtype=bool))
        overlap = jnp.max(jnp.where(pair, robots.radius[:, None] + robots.radius[None, :] - gap,
                                    -jnp.inf))
        contacts = jnp.sum(info["collision_robot"]) + jnp.sum(info["collision_wall"])
        worst = {"non_finite": worst["non_finite"] + bad,
                 "robot_wall": jnp.maximum(worst["robot_wall"], robot_wall),
                 "human_wall": jnp.maximum(worst["human_wall"], human_wall),
                 "robot_robot": jnp.maximum(worst["robot_robot"], overlap),
                 "contacts": worst["contacts"] + contacts,
                 "robot_steps": worst["robot_steps"] + jnp.sum(info["was_active"])}
        return (state, key, worst), None

    @jax.jit
    def run(state, key, worst, t0):
        (state, key, worst), _ = jax.lax.scan(one, (state, key, worst),
                                              t0 + jnp.arange(chunk))
        return state, key, worst

    key = jax.random.key(0)
    _, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(key, num_envs), params)
    worst = {"non_finite": jnp.zeros((), jnp.int32), "robot_wall": -jnp.inf,
             "human_wall": -jnp.inf, "robot_robot": -jnp.inf,
             "contacts": jnp.zeros((), jnp.int32), "robot_steps": jnp.zeros((), jnp.int32)}
    worst = jax.tree.map(jnp.asarray, worst)
    t0 = time.perf_counter()
    compiled = run.lower(state, key, worst, 0).compile()
    compile_s = time.perf_counter() - t0
    calls = math.ceil(agent_steps / (num_envs * count * chunk))
    t0 = time.perf_counter()
    for i in range(calls):
        state, key, worst = compiled(state, key, worst, i * chunk)
    worst = jax.device_get(worst)
    seconds = time.perf_counter() - t0
    made = calls * num_envs * count * chunk
    return {"case": name, "scenario": scenario, "robot-steps": made,
            "active robot-steps": int(worst["robot_steps"]), "non-finite": int(worst["non_finite"]),
            "robot in wall (m)": max(float(worst["robot_wall"]), 0.0),
            "pedestrian in wall (m)": (max(float(worst["human_wall"]), 0.0)
                                       if np.isfinite(worst["human_wall"]) else None),
            "robot overlap (m)": max(float(worst["robot_robot"]), 0.0),
            "contacts": int(worst["contacts"]), "rate": made / seconds, "compile": compile_s}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--agent-steps", type=float, default=1e7,
                        help="robot-steps per case (every slot, active or not)")
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    parser.add_argument("--num-envs", type=int, default=256)
    parser.add_argument("--chunk", type=int, default=500, help="steps per compiled call")
    args = parser.parse_args()
    print(f"machine: {cpu_model()}, jax {jax.__version__} on {jax.default_backend()}; "
          f"{args.agent_steps:,.0f} robot-steps per case")
    print("| case | scenario | robot-steps | non-finite | robot in wall (m) | pedestrian in wall "
          "(m) | robot overlap (m) | contacts | robot-steps/s | compile (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in args.cases:
        r = stress(name, args.agent_steps, args.num_envs, args.chunk)
        human = "-" if r["pedestrian in wall (m)"] is None else f"{r['pedestrian in wall (m)']:.3f}"
        print(f"| {r['case']} | {r['scenario']} | {r['robot-steps']:,} | {r['non-finite']} | "
              f"{r['robot in wall (m)']:.3f} | {human} | {r['robot overlap (m)']:.3f} | "
              f"{r['contacts']:,} | {r['rate']:,.0f} | {r['compile']:.1f} |", flush=True)


if __name__ == "__main__":
    main()
