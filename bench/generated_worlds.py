"""Generated worlds: how fast they are made, what a generating ``reset`` costs to compile, and
what a new world at every episode costs a training run, beside the fixed map in the same run.

    python bench/generated_worlds.py [--batch 1024] [--updates 4]

Prints, for each family (``sgjax.maps.generated``): the compile time and the rate of drawing
worlds as a reset draws them (built, compiled to map arrays and checked, the dilemma apart)
and with the dilemma check too (as ``sgjax maps generate`` draws them), in batches of
``--batch``; the compile time
of ``jit(vmap(reset))`` beside the fixed map's; and the training throughput (env steps/s, best
of two calls of ``--updates`` updates) of the main job's config (``train/configs/doorway.yaml``)
on the shipped doorway and on ``generated:doorway`` (a new world at every episode).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
from compiled import compile_measured

import sgjax
from sgjax.environment.worlds import source_for
from sgjax.maps.generated.families import FAMILIES
from train.algorithm.config import load_config
from train.algorithm.trainer import Trainer, seed_keys

CONFIG = Path(__file__).resolve().parents[1] / "train/configs/doorway.yaml"


def best_of(fn, *args, repeats: int = 3) -> float:
    """The fastest of ``repeats`` calls (s), after one warm-up call."""
    jax.block_until_ready(fn(*args))
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        best = min(best, time.perf_counter() - t0)
    return best


def generation(batch: int, families: list[str]) -> None:
    print(f"worlds drawn in batches of {batch}, each compiled to map arrays and checked as a "
          "reset checks it (the dilemma apart)")
    for name in families:
        source = source_for(name, check_dilemma=False)
        keys = jax.random.split(jax.random.key(0), batch)
        draw, compile_s, _ = compile_measured(jax.jit(jax.vmap(source.draw)).lower(keys))
        seconds = best_of(draw, keys)
        with_dilemma = source_for(name)
        audit = jax.jit(jax.vmap(with_dilemma.draw)).lower(keys).compile()
        print(f"  {name:>10}: compile {compile_s:5.1f} s, {batch / seconds:9,.0f} worlds/s; "
              f"with the dilemma check {batch / best_of(audit, keys):9,.0f} worlds/s")


def reset_compile(envs: int) -> None:
    print(f"compile of jit(vmap(reset)) over {envs} environments, 4 robots")
    for scenario in ("doorway", "generated:doorway", "hallway", "generated:hallway"):
        env, params = sgjax.make(scenario, num_agents=4)
        keys = jax.random.split(jax.random.key(0), envs)
        reset, compile_s, _ = compile_measured(
            jax.jit(jax.vmap(env.reset, in_axes=(0, None))).lower(keys, params))
        seconds = best_of(reset, keys, params)
        print(f"  {scenario:>18}: compile {compile_s:5.1f} s, {envs / seconds:9,.0f} resets/s")


def training(updates: int) -> None:
    print(f"training throughput, the main job's config ({CONFIG.name}), {updates} updates per "
          "call, best of two calls")
    rates = {}
    for scenario in ("doorway", "generated:doorway"):
        config = load_config(CONFIG, [f"env.scenarios=[{scenario!r}]"])
        trainer = Trainer(config)
        runner = jax.jit(jax.vmap(trainer.init))(seed_keys(config))
        chunk, compile_s, _ = compile_measured(trainer.jitted_chunk_lanes(updates).lower(runner))
        runner, _ = chunk(runner)
        best = float("inf")
        for _ in range(2):
            t0 = time.perf_counter()
            runner, logs = chunk(runner)
            jax.block_until_ready(logs)
            best = min(best, time.perf_counter() - t0)
        rates[scenario] = updates * config.algorithm.steps_per_update / best
        print(f"  {scenario:>18}: compile {compile_s:5.1f} s, {rates[scenario]:9,.0f} env "
              "steps/s")
    print(f"  generated / fixed: {rates['generated:doorway'] / rates['doorway']:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--batch", type=int, default=1024)
    parser.add_argument("--envs", type=int, default=256)
    parser.add_argument("--updates", type=int, default=4)
    parser.add_argument("--families", nargs="+", choices=list(FAMILIES), default=list(FAMILIES))
    parser.add_argument("--skip-training", action="store_true")
    parser.add_argument("--skip-resets", action="store_true")
    args = parser.parse_args()
    print(f"jax {jax.__version__} on {jax.devices()[0].device_kind}")
    generation(args.batch, args.families)
    if not args.skip_resets:
        reset_compile(args.envs)
    if not args.skip_training:
        training(args.updates)


if __name__ == "__main__":
    main()
