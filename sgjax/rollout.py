"""The main job until the trainer lands: a batched rollout of a shipped scenario.

Runs ``num_envs`` episodes at once with ``jit(scan(vmap(step)))`` under a built-in policy,
prints progress and throughput, a table of episode metrics, and writes a GIF of one episode::

    sgjax-rollout --scenario doorway --num-agents 4 --num-envs 1024 --steps 600

Policies: ``go`` (always GO: the local planner alone, the paper's "Only Local" ablation) and
``random`` (GO, or STOP with probability ``--stop-prob``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import sgjax
from sgjax.render import render_state, save_gif


def policy_fn(name: str, stop_prob: float, shape: tuple[int, ...]):
    if name == "go":
        return lambda key: jnp.zeros(shape, jnp.int32)
    if name == "random":
        return lambda key: (jax.random.uniform(key, shape) < stop_prob).astype(jnp.int32)
    raise ValueError(f"--policy must be 'go' or 'random', got {name!r}")


def batched_rollout(env, params, num_envs: int, chunk: int, policy: str, stop_prob: float):
    """A jitted function running ``chunk`` steps of ``num_envs`` environments and summing
    episode statistics over the episodes that end."""
    act = policy_fn(policy, stop_prob, (num_envs, env.max_agents))
    vstep = jax.vmap(env.step, in_axes=(0, 0, 0, None))

    def one_step(state, key):
        k_act, k_step = jax.random.split(key)
        _, state, _, _, _, info = vstep(jax.random.split(k_step, num_envs), state, act(k_act),
                                        params)
        done = info["episode_done"]
        robots = info["final_robots"]
        present = jnp.sum(robots.present, axis=1)
        reached = jnp.sum(robots.present & robots.succeeded, axis=1)
        collisions = info["final_collisions"]
        stats = {
            "episodes": jnp.sum(done),
            "robots": jnp.sum(jnp.where(done, present, 0)),
            "robots_reached": jnp.sum(jnp.where(done, reached, 0)),
            "team_success": jnp.sum(done & (reached == present)),
            "robot_collisions": jnp.sum(jnp.where(done[:, None], collisions.robot, 0)),
            "wall_collisions": jnp.sum(jnp.where(done[:, None], collisions.wall, 0)),
            "steps": jnp.sum(jnp.where(done, info["final_time"], 0)),
        }
        return state, stats

    @jax.jit
    def run(state, key):
        state, stats = jax.lax.scan(one_step, state, jax.random.split(key, chunk))
        return state, jax.tree.map(jnp.sum, stats)

    return run


def record_episode(env, params, key, policy: str, stop_prob: float, max_frames: int = 300):
    """Step one environment (no auto-reset) until every robot is done; return host arrays."""
    act = policy_fn(policy, stop_prob, (env.max_agents,))
    step = jax.jit(env.step_env)
    key, k_reset = jax.random.split(key)
    _, state = env.reset(k_reset, params)
    frames = [state]
    for _ in range(int(params.max_steps)):
        key, k_act, k_step = jax.random.split(key, 3)
        _, state, _, term, trunc, _ = step(k_step, state, act(k_act), params)
        frames.append(state)
        if bool(jnp.all(~state.robots.present | term | trunc)):
            break
    stride = max(1, len(frames) // max_frames)
    return frames[::stride], stride


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default="doorway", help=f"one of {sgjax.registered()}")
    parser.add_argument("--num-agents", type=int, default=4)
    parser.add_argument("--num-envs", type=int, default=1024)
    parser.add_argument("--steps", type=int, default=1600,
                        help="steps of every environment (at least two time limits, so that "
                             "slow episodes count too)")
    parser.add_argument("--policy", default="go", choices=["go", "random"])
    parser.add_argument("--stop-prob", type=float, default=0.2)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="runs/rollout", help="folder for episode.gif")
    args = parser.parse_args(argv)

    env, params = sgjax.make(args.scenario, num_agents=args.num_agents)
    print(f"sgjax {sgjax.__version__}, jax {jax.__version__} on {jax.devices()[0].platform}: "
          f"{args.scenario}, {args.num_agents} robots x {args.num_envs} environments, "
          f"policy {args.policy}, dt {float(params.dt):g} s, "
          f"time limit {int(params.max_steps)} steps")
    if args.steps < int(params.max_steps):
        print(f"warning: --steps {args.steps} is shorter than the time limit: only episodes "
              "that end early are counted, which flatters the success rate")
    key = jax.random.key(args.seed)
    key, k_reset = jax.random.split(key)
    _, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(k_reset, args.num_envs),
                                                       params)
    chunks = 10
    chunk = max(1, args.steps // chunks)
    run = batched_rollout(env, params, args.num_envs, chunk, args.policy, args.stop_prob)
    t0 = time.perf_counter()
    compiled = run.lower(state, key).compile()
    print(f"compiled in {time.perf_counter() - t0:.1f} s")
    totals: dict[str, float] = {}
    elapsed = 0.0
    for i in range(chunks):
        key, k = jax.random.split(key)
        t0 = time.perf_counter()
        state, stats = compiled(state, k)
        stats = jax.device_get(stats)
        elapsed += time.perf_counter() - t0
        for name, value in stats.items():
            totals[name] = totals.get(name, 0.0) + float(value)
        done_steps = (i + 1) * chunk
        rate = done_steps * args.num_envs / elapsed
        bar = "#" * (i + 1) + "." * (chunks - i - 1)
        print(f"[{bar}] step {done_steps:>5}/{chunk * chunks}  {rate:>12,.0f} env-steps/s  "
              f"{rate * args.num_agents:>13,.0f} agent-steps/s  "
              f"episodes {int(totals['episodes'])}", flush=True)

    episodes = max(totals["episodes"], 1.0)
    robots = max(totals["robots"], 1.0)
    dt = float(params.dt)
    running = int(jnp.sum(state.time > 0))
    rows = [
        ("episodes finished", f"{int(totals['episodes'])}"),
        ("episodes still running (not counted)", f"{running}"),
        ("team success (every robot)", f"{totals['team_success'] / episodes:.3f}"),
        ("robot success", f"{totals['robots_reached'] / robots:.3f}"),
        ("robot-robot collisions / episode", f"{totals['robot_collisions'] / episodes:.2f}"),
        ("robot-wall collisions / episode", f"{totals['wall_collisions'] / episodes:.2f}"),
        ("mean episode length (s)", f"{totals['steps'] * dt / episodes:.1f}"),
        ("throughput (agent-steps/s)",
         f"{chunk * chunks * args.num_envs * args.num_agents / elapsed:,.0f}"),
    ]
    width = max(len(r[0]) for r in rows)
    print("\n| " + "metric".ljust(width) + " | value |\n|" + "-" * (width + 2) + "|-------|")
    for name, value in rows:
        print(f"| {name.ljust(width)} | {value} |")

    frames, stride = record_episode(env, params, key, args.policy, args.stop_prob)
    spec = sgjax.maps.load(args.scenario)
    radius = np.asarray(params.robots.radius)
    images = []
    for t, s in enumerate(frames):
        trail = np.stack([np.asarray(f.robots.position) for f in frames[max(0, t - 15):t + 1]])
        images.append(render_state(spec, s, radius, trail=trail,
                                   title=f"{args.scenario}  t = {t * stride * dt:.1f} s"))
    fps = max(1, round(1 / (dt * stride)))
    path = save_gif(images, Path(args.out) / "episode.gif", fps=fps)
    print(f"\nwrote {path} ({len(images)} frames)")


if __name__ == "__main__":
    main()
