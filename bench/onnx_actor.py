"""Latency of one decision of a trained actor exported to ONNX (onnxruntime, CPU) beside the
same actor in JAX (jitted), issue 69's target.

The actor is a run of ``--config`` (default the transfer specialist's: an MLP of 128 x 128 on
the ``transfer`` observations, GO/STOP), initialised rather than trained (its latency does not
depend on its weights), exported by ``train.run.onnx_export``; each decision is one call for
``--robots`` rows, timed over ``--calls`` calls after a warm-up, best of ``--repeats``.

    python bench/onnx_actor.py
    python bench/onnx_actor.py --config train/configs/transfer_doorway.yaml --robots 4 10
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import jax
import numpy as np

from train.algorithm.config import load_config
from train.algorithm.trainer import Trainer, seed_keys
from train.run.checkpoint import save
from train.run.onnx_export import OnnxActor, decision_function, export_onnx, load_actor


def best_per_call(fn, calls: int, repeats: int) -> float:
    """Best over ``repeats`` of the mean seconds per call of ``calls`` calls."""
    fn()
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(calls):
            fn()
        best = min(best, (time.perf_counter() - start) / calls)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", default="train/configs/transfer_doorway.yaml")
    parser.add_argument("--robots", type=int, nargs="+", default=[1, 4, 10])
    parser.add_argument("--calls", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    config = load_config(args.config, ["num_seeds=1"])
    with tempfile.TemporaryDirectory() as folder:
        trainer = Trainer(config)
        runner = jax.jit(jax.vmap(trainer.init))(seed_keys(config))
        run = Path(folder) / "run"
        save(run / "checkpoints" / "latest.msgpack", config, runner, {}, trainer.actor)
        model, _ = export_onnx(run, Path(folder) / "actor.onnx")
        _, _, layout, weights, _ = load_actor(run)
        decide = jax.jit(decision_function(config.network, layout, weights))
        onnx = OnnxActor(model)
        print(f"jax {jax.__version__}, {os.cpu_count()} CPU(s); {args.config}: network "
              f"{config.network.kind} {list(config.network.hidden)}, observation "
              f"{layout.obs_size}; load average "
              + " ".join(f"{v:.2f}" for v in os.getloadavg()))
        print(f"{'robots':>7}{'JAX (jit) us':>15}{'ONNX Runtime us':>18}")
        rng = np.random.default_rng(0)
        for robots in args.robots:
            obs = rng.normal(size=(robots, layout.obs_size)).astype(np.float32)
            jax_s = best_per_call(lambda obs=obs: jax.block_until_ready(decide(obs)),
                                  args.calls, args.repeats)
            onnx_s = best_per_call(lambda obs=obs: onnx(obs), args.calls, args.repeats)
            print(f"{robots:>7}{jax_s * 1e6:>15.1f}{onnx_s * 1e6:>18.1f}")


if __name__ == "__main__":
    main()
