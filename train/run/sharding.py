"""Spreading the environment batch over all local devices with ``jax.sharding``.

The runner state is laid out ``[seeds, ...]``; its per-environment fields (environment states,
observations, returns, episode flags) have the environment axis second and the network memory
has the agent axis (environments x slots) second. Those axes are split over a one-axis device
mesh named ``"env"``; everything else (network, optimiser, statistics, keys) is replicated.
``jit`` then partitions the whole update (XLA's SPMD partitioner), gathering where the update
needs the whole batch (normalisation statistics, minibatches).

Multi-host: start every host with ``jax.distributed.initialize()`` (coordinator address,
process count and id from the cluster) before building the trainer; ``jax.devices()`` then
lists every host's devices, and the same mesh over them spreads the batch across hosts. Each
host must run the same program; ``num_envs`` must divide evenly over all devices.
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from sgjax.terms.base import ConfigError

PER_ENV_FIELDS = ("env_states", "obs", "returns", "episode_return", "starts")
PER_AGENT_FIELDS = ("carry",)


def device_mesh(devices: list | None = None) -> Mesh:
    return Mesh(np.asarray(devices if devices is not None else jax.devices()), ("env",))


def shard_runner(runner: Any, mesh: Mesh, num_envs: int) -> Any:
    """Place a seed-batched ``RunnerState`` on ``mesh`` (see the module doc)."""
    count = mesh.devices.size
    if num_envs % count:
        raise ConfigError(f"algorithm.num_envs ({num_envs}) must be a multiple of the "
                          f"{count} devices to shard over")
    split = NamedSharding(mesh, PartitionSpec(None, "env"))
    whole = NamedSharding(mesh, PartitionSpec())
    fields = {}
    for name in runner.__dataclass_fields__:
        value = getattr(runner, name)
        sharding = split if name in PER_ENV_FIELDS + PER_AGENT_FIELDS else whole
        fields[name] = jax.tree.map(
            lambda leaf, s=sharding: jax.device_put(leaf, s if leaf.ndim >= 2 else whole),
            value)
    return runner.replace(**fields)
