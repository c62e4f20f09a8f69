"""Sweeps over several processes or hosts through JAX's own multi-process runtime.

A sweep (ablation lanes, seeds) wider than one machine holds is split over processes: every
process runs the same command with its own ``--process-id``, trains its share of the lanes
(:func:`lane_share`, a contiguous block), and :func:`gather_lanes` collects every process's
results in lane order on every process (an all-gather over ``jax.distributed``'s devices; on the
CPU through the gloo collectives). Process 0 writes the outputs.

    # host A (the coordinator)                 # host B
    python -m train.ablation ... \\             python -m train.ablation ... \\
      --coordinator hostA:29500 \\               --coordinator hostA:29500 \\
      --num-processes 2 --process-id 0           --num-processes 2 --process-id 1

The coordinator address is any ``host:port`` every process can reach (process 0 listens
there). Nothing but the results crosses between processes: each process's training is its own
compiled program on its own devices.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

import jax
import numpy as np


@dataclass(frozen=True)
class Processes:
    """Which process of how many this is (``index`` in ``[0, count)``)."""

    index: int = 0
    count: int = 1

    @property
    def is_main(self) -> bool:
        return self.index == 0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group(
        "multi-process sweep (jax.distributed; see train/run/multiprocess.py)")
    group.add_argument("--coordinator", default=None, metavar="HOST:PORT",
                       help="address of process 0; every process passes the same one")
    group.add_argument("--num-processes", type=int, default=1,
                       help="processes sharing the sweep (default 1: no multi-process run)")
    group.add_argument("--process-id", type=int, default=0, help="this process, 0-based")


def initialize(coordinator: str | None, num_processes: int, process_id: int) -> Processes:
    """Start JAX's multi-process runtime when ``num_processes > 1`` (before anything else
    touches JAX's backends); returns this process's place. Errors name the argument."""
    if num_processes < 1:
        raise ValueError(f"--num-processes must be at least 1, got {num_processes}")
    if not 0 <= process_id < num_processes:
        raise ValueError(f"--process-id must be in [0, {num_processes}), got {process_id}")
    if num_processes == 1:
        return Processes()
    if not coordinator or ":" not in coordinator:
        raise ValueError(f"--coordinator must be HOST:PORT for {num_processes} processes, got "
                         f"{coordinator!r}")
    # Cross-process collectives on the CPU need an implementation; gloo ships with jaxlib.
    # (GPUs use NCCL whatever this says.)
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(coordinator_address=coordinator, num_processes=num_processes,
                               process_id=process_id)
    return Processes(jax.process_index(), jax.process_count())


def lane_share(count: int, processes: Processes) -> np.ndarray:
    """The lanes ``[first, last)`` of ``range(count)`` that ``processes.index`` runs: contiguous
    blocks, the first ``count % processes.count`` processes taking one more. May be empty."""
    base, extra = divmod(count, processes.count)
    first = processes.index * base + min(processes.index, extra)
    return np.arange(first, first + base + (processes.index < extra))


def gather_lanes(mine: np.ndarray, count: int, processes: Processes) -> np.ndarray:
    """Every process's ``mine`` (``[len(lane_share(count)), ...]``, float) put together in lane
    order: ``[count, ...]`` on every process. One all-gather; every process must call it."""
    mine = np.asarray(mine, np.float64)
    if processes.count == 1:
        return mine
    from jax.experimental import multihost_utils

    width = -(-count // processes.count)
    padded = np.full((width, *mine.shape[1:]), np.nan)
    padded[:len(mine)] = mine
    # float64 travels as float32 unless x64 is on; sweep results are means of a few episodes.
    gathered = np.asarray(multihost_utils.process_allgather(padded.astype(np.float32)),
                          np.float64)
    parts = [gathered[p, :len(lane_share(count, Processes(p, processes.count)))]
             for p in range(processes.count)]
    return np.concatenate(parts)
