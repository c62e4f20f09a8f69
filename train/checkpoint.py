"""Checkpoints: one self-contained msgpack file per save (Flax serialisation).

A file holds the run's configuration (YAML text), metadata (JSON text: steps, updates, best
success, wall time) and the whole ``RunnerState`` of every seed (network, optimiser,
normalisation statistics, environment states, random keys), so that a resumed run continues
exactly where it stopped. Files are written to a temporary name and renamed into place, so a
run killed mid-write loses at most one checkpoint interval.

A run folder ``out/`` holds ``checkpoints/latest.msgpack`` and ``checkpoints/best.msgpack``;
``sgjax evaluate --policy out/`` (or a ``.msgpack`` path) evaluates the best one.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import jax
import yaml
from flax import serialization

from train.config import TrainConfig, config_from_dict


def save(path: str | Path, config: TrainConfig, runner: Any, meta: dict[str, Any]) -> Path:
    """Write ``runner`` (seed-batched) with its config and ``meta`` to ``path`` atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "config": yaml.safe_dump(config.to_dict(), sort_keys=False),
        "meta": json.dumps(meta),
        "runner": serialization.to_state_dict(jax.device_get(runner)),
    }
    temporary = path.with_name(path.name + ".tmp")
    temporary.write_bytes(serialization.msgpack_serialize(payload))
    os.replace(temporary, path)
    return path


def read(path: str | Path) -> tuple[TrainConfig, dict[str, Any], dict[str, Any]]:
    """``(config, meta, raw runner state dict)`` of a checkpoint file."""
    path = resolve(path)
    try:
        payload = serialization.msgpack_restore(path.read_bytes())
        config = config_from_dict(yaml.safe_load(payload["config"]), str(path))
        return config, json.loads(payload["meta"]), payload["runner"]
    except (KeyError, ValueError, TypeError) as err:
        raise ValueError(f"{path}: not a readable sgjax training checkpoint ({err})") from err


def restore(path: str | Path, trainer: Any, contents: tuple | None = None
            ) -> tuple[Any, dict[str, Any]]:
    """The seed-batched ``RunnerState`` and meta of a checkpoint, for ``trainer``
    (``contents``: what :func:`read` already returned for ``path``)."""
    from train.ppo import seed_keys

    _, meta, raw = contents if contents is not None else read(path)
    template = jax.eval_shape(jax.vmap(trainer.init), seed_keys(trainer.config))
    try:
        runner = serialization.from_state_dict(template, raw)
    except (KeyError, ValueError) as err:
        raise ValueError(f"{resolve(path)}: does not fit this configuration ({err})") from err
    return jax.tree.map(jax.numpy.asarray, runner), meta


def resolve(path: str | Path) -> Path:
    """A checkpoint file from a file path or a run folder (its best, else its latest)."""
    path = Path(path)
    if path.is_dir():
        for candidate in (path / "checkpoints" / "best.msgpack",
                          path / "checkpoints" / "latest.msgpack", path / "best.msgpack",
                          path / "latest.msgpack"):
            if candidate.is_file():
                return candidate
        raise ValueError(f"{path}: no checkpoints/best.msgpack or latest.msgpack in this folder")
    if not path.is_file():
        raise ValueError(f"{path}: no such checkpoint file")
    return path


def make_kwargs(path: str | Path) -> dict[str, Any]:
    """The ``sgjax.make`` settings the checkpoint's policy was trained with."""
    config, _, _ = read(path)
    return config.env.make_kwargs()


def load_policy(path: str | Path, env: Any = None, seed_index: int | None = None,
                deterministic: bool | None = None):
    """The trained actor of a checkpoint as an ``sgjax`` policy: actions sampled from it, or
    greedy with ``deterministic`` (default: the run's ``evaluation.deterministic``). The seed
    is ``seed_index``, else the one the checkpoint's meta names as best, else 0."""
    from train.ppo import Trainer

    contents = read(path)
    config = contents[0]
    trainer = Trainer(config)
    runner, meta = restore(path, trainer, contents)
    index = seed_index if seed_index is not None else int(meta.get("best_seed", 0))
    if not 0 <= index < config.num_seeds:
        raise ValueError(f"{resolve(path)}: seed index {index} out of range "
                         f"(the run has {config.num_seeds} seeds)")
    pick = lambda x: x[index]  # noqa: E731
    if env is not None and env.observation_size != trainer.batch.obs_size:
        raise ValueError(f"{resolve(path)}: the policy reads observations of size "
                         f"{trainer.batch.obs_size}, this environment gives "
                         f"{env.observation_size}; build it with the checkpoint's settings "
                         "(sgjax evaluate does)")
    if deterministic is None:
        deterministic = config.evaluation.deterministic
    return trainer.policy(jax.tree.map(pick, runner.params),
                          jax.tree.map(pick, runner.obs_stats), deterministic,
                          pick(runner.obs_mask))
