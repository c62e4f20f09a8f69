"""Checkpoints: one self-contained msgpack file per save (Flax serialisation).

A file holds the run's configuration (YAML text; the environment's ``sgjax.make`` options
nested by group, ``MakeOptions.to_dict``, under ``env.options``), metadata (JSON text: steps,
updates, best success, wall time) and the whole ``RunnerState`` of every seed (network,
optimiser, normalisation statistics, environment states, random keys), so that a resumed run
continues exactly where it stopped. Files are written to a temporary name and renamed into
place, so a run killed mid-write loses at most one checkpoint interval.

The meta also holds the actor's layout (``train.algorithm.actor.ActorLayout``: observation size,
action head, where the ``others`` block sits), so :func:`load_checkpoint_policy` rebuilds the acting
policy from
the file alone, without a ``Trainer`` or the training environments.

A run folder ``out/`` holds ``checkpoints/latest.msgpack`` (the final weights) and
``checkpoints/best.msgpack`` (the best periodic evaluation's); ``sgjax evaluate --policy out/``
evaluates the ones the run's own final evaluation judged (:func:`judged_checkpoint`: the final
weights unless its config says ``evaluation.checkpoint: best``), a ``.msgpack`` path that file:
:data:`LOADER`
is registered with ``sgjax.evaluation.policies`` when this module is imported, and through the
``sgjax.policy_loaders`` entry point group (pyproject.toml) when only ``sgjax`` is.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import yaml
from flax import serialization

from sgjax.environment.options import MakeOptions
from sgjax.environment.registry import make
from sgjax.evaluation.policies import register_loader
from sgjax.files import write_atomic
from train.algorithm.actor import ActorLayout, ActorWeights, acting_policy
from train.algorithm.config import TrainConfig, config_from_dict
from train.algorithm.networks import others_layout
from train.algorithm.normalize import RunningStats


def save(path: str | Path, config: TrainConfig, runner: Any, meta: dict[str, Any],
         actor: ActorLayout | None = None) -> Path:
    """Write ``runner`` (seed-batched) with its config and ``meta`` to ``path`` atomically;
    ``actor`` (``Trainer.actor``) goes into the meta so that the policy loads on its own."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if actor is not None:
        meta = {**meta, "actor": actor.to_dict()}
    payload = {
        "config": yaml.safe_dump(config.to_dict(), sort_keys=False),
        "meta": json.dumps(meta),
        "runner": serialization.to_state_dict(jax.device_get(runner)),
    }
    return write_atomic(path, serialization.msgpack_serialize(payload))


ACTING_KEYS = ("params", "obs_stats", "obs_mask")  # what evaluation and export read


def save_acting(source: str | Path, path: str | Path) -> Path:
    """Write the acting part of the checkpoint ``source`` (a file or run folder) to ``path``:
    its config, meta and, of the runner state, the network parameters and the observation
    statistics and mask (every seed): what evaluation, ``train.transfer`` and export read,
    without the optimiser state, environments and level buffers (a 5-seed curriculum run:
    62 MB -> about 1 MB). It cannot resume training."""
    payload = serialization.msgpack_restore(resolve(source).read_bytes())
    runner = payload["runner"]
    payload["runner"] = {k: runner[k] for k in ACTING_KEYS if runner.get(k) is not None}
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_atomic(path, serialization.msgpack_serialize(payload))


def checkpoint_due(done: int, per_call: int, total: int, times: int) -> bool:
    """Whether a run of ``total`` updates, trained in calls of ``per_call`` updates and
    checkpointed about ``times`` times, saves after the call that brought it to ``done``: at
    the first call past each multiple of ``ceil(total / times)`` updates, and at the end (a
    run of 122 updates in calls of 2 saves 10 times, not 61)."""
    every = max(1, -(-total // times))
    return done >= total or done // every > (done - per_call) // every


def read(path: str | Path) -> tuple[TrainConfig, dict[str, Any], dict[str, Any]]:
    """``(config, meta, raw runner state dict)`` of a checkpoint file."""
    path = resolve(path)
    try:
        payload = serialization.msgpack_restore(path.read_bytes())
        data = yaml.safe_load(payload["config"])
        env = data.get("env") if isinstance(data, dict) else None
        if isinstance(env, dict) and "options" not in env and "arrived" not in env:
            # Written before checkpoints recorded it (2026-11-25), when the default was "park"
            # (arrived robots stop where they arrive); "settle" is the default since. (Such
            # files, like every one before the nested ``options``, hold their make options as
            # flat keys of the env section, which the config reader still takes.)
            env["arrived"] = "park"
        config = config_from_dict(data, str(path))
        return config, json.loads(payload["meta"]), payload["runner"]
    except (KeyError, ValueError, TypeError) as err:
        raise ValueError(f"{path}: not a readable sgjax training checkpoint ({err})") from err


def restore(path: str | Path, trainer: Any, contents: tuple | None = None
            ) -> tuple[Any, dict[str, Any]]:
    """The seed-batched ``RunnerState`` and meta of a checkpoint, for ``trainer``
    (``contents``: what :func:`read` already returned for ``path``)."""
    from train.algorithm.trainer import seed_keys

    _, meta, raw = contents if contents is not None else read(path)
    template = jax.eval_shape(jax.vmap(trainer.init), seed_keys(trainer.config))
    if isinstance(raw, dict) and "hyper" not in raw:
        # Saved before the runner state held its lane settings (2026-11-25): the run used the
        # configured values, as a fresh run's state holds them.
        seeds = trainer.config.num_seeds
        raw = {**raw, "hyper": {name: np.full(seeds, value, np.float32) for name, value
                                in trainer.default_hyper().items()}}
    try:
        runner = state_from_raw(template, raw)
    except (KeyError, ValueError) as err:
        raise ValueError(f"{resolve(path)}: does not fit this configuration ({err})") from err
    return jax.tree.map(jax.numpy.asarray, runner), meta


# Fields the runner state gained on 2026-11-28 (curricula over generated worlds, pedestrians
# in them) and 2026-11-29 (``HumanState.replay``: None unless recorded people are replayed): a
# checkpoint saved before lacks them, and held what these defaults say.
ADDED_FIELDS = ("levels", "curriculum", "next_level", "seed", "humans", "pedestrians",
                "replay")
ADDED_FILL = {"pedestrians": -1}  # an array field's value before it existed, where not 0


def with_added_fields(raw: Any, shapes: Any) -> Any:
    """A checkpoint's raw state with the :data:`ADDED_FIELDS` it lacks, at the value a run
    made before them held: zeros for arrays (``WorldDraw.seed``: no seed) but those of
    :data:`ADDED_FILL` (``pedestrians``: -1, the environment's count), empty for
    containers (``RunnerState.levels``, ``curriculum``) and None (``EnvState.next_level``,
    ``WorldDraw.humans``, ``HumanState.replay``). ``shapes``: the state dict of the
    trainer's runner template (``ShapeDtypeStruct`` leaves). Any other missing field stays
    missing (the checkpoint does not fit: :func:`restore` says so)."""
    if not isinstance(shapes, dict) or not isinstance(raw, dict):
        return raw
    out = dict(raw)
    for name, shape in shapes.items():
        if name in raw:
            out[name] = with_added_fields(raw[name], shape)
        elif name in ADDED_FIELDS:
            fill = ADDED_FILL.get(name, 0)
            out[name] = jax.tree.map(lambda s, f=fill: np.full(s.shape, f, s.dtype), shape)
    return out


def state_from_raw(template: Any, raw: Any) -> Any:
    """A saved runner state (a checkpoint's, a partial file's) in ``template``'s structure
    (a runner, or its ``jax.eval_shape``), the :data:`ADDED_FIELDS` it lacks filled
    (:func:`with_added_fields`); flax's error where it does not fit otherwise."""
    return serialization.from_state_dict(
        template, with_added_fields(raw, serialization.to_state_dict(template)))


def judged_checkpoint(out: Path, config: TrainConfig) -> Path:
    """The checkpoint the final evaluation of the run in ``out`` judges:
    ``checkpoints/latest.msgpack`` (the weights training ended with: every sgjax command's
    rule), or ``checkpoints/best.msgpack`` with ``evaluation.checkpoint: best``."""
    return out / "checkpoints" / f"{_JUDGED[config.evaluation.checkpoint]}.msgpack"


_JUDGED = {"final": "latest", "best": "best"}  # evaluation.checkpoint -> the file's stem


def _judged_stem(folder: Path) -> str:
    """The stem of the checkpoint a run folder stands for: its ``config.yaml``'s
    ``evaluation.checkpoint`` (``final`` where it names none), also for the run's
    ``checkpoints/`` folder itself."""
    for config in (folder / "config.yaml", folder.parent / "config.yaml"):
        if config.is_file():
            data = yaml.safe_load(config.read_text()) or {}
            rule = (data.get("evaluation") or {}).get("checkpoint", "final")
            if rule not in _JUDGED:
                raise ValueError(f"{config}: evaluation.checkpoint must be one of "
                                 f"{tuple(_JUDGED)}, got {rule!r}")
            return _JUDGED[rule]
    return _JUDGED["final"]


def resolve(path: str | Path) -> Path:
    """A checkpoint file from a file path, or from a run folder (or its ``checkpoints/``
    folder) the weights its final evaluation judged (:func:`judged_checkpoint`)."""
    path = Path(path)
    if path.is_dir():
        name = f"{_judged_stem(path)}.msgpack"
        for candidate in (path / "checkpoints" / name, path / name):
            if candidate.is_file():
                return candidate
        raise ValueError(f"{path}: no checkpoints/{name} in this folder (the weights the run's "
                         "final evaluation judges; evaluation.checkpoint in its config.yaml)")
    if not path.is_file():
        raise ValueError(f"{path}: no such checkpoint file")
    return path


def training_options(path: str | Path) -> MakeOptions:
    """The ``sgjax.make`` options the checkpoint's policy was trained in (robot counts
    aside)."""
    config, _, _ = read(path)
    return config.env.options


def is_checkpoint(spec: Any) -> bool:
    """Whether ``spec`` names a trainer checkpoint file or run folder."""
    if not isinstance(spec, str | Path):
        return False
    path = Path(spec)
    return path.suffix == ".msgpack" or (path.is_dir() and (
        (path / "checkpoints").is_dir() or any(path.glob("*.msgpack"))))


def actor_layout(path: str | Path, config: TrainConfig, meta: dict[str, Any],
                 raw: dict[str, Any], env: Any = None) -> ActorLayout:
    """The actor's layout: from the meta, or for checkpoints saved before it was kept there,
    rebuilt from the weights and the configuration (and, for an ``others`` encoder, from
    ``env`` or one environment of the first training scenario)."""
    if "actor" in meta:
        return ActorLayout.from_dict(meta["actor"])
    params = raw["params"]["params"]
    discrete = "log_std" not in params
    others = None
    if config.network.others_encoder != "none":
        if env is None:
            try:
                env, _ = make(config.env.scenarios[0], options=config.env.options,
                              num_agents=config.env.curriculum[0][1],
                              max_agents=config.env.slots)
            except (ValueError, KeyError, TypeError) as err:
                raise ValueError(
                    f"{resolve(path)}: this checkpoint predates saved actor layouts, and its "
                    f"others encoder needs the observation layout of its training scenario "
                    f"{config.env.scenarios[0]!r}, which cannot be built here ({err}); pass "
                    "the environment to load_checkpoint_policy(path, env)") from err
        others = others_layout(env)
    return ActorLayout(
        obs_size=int(np.shape(raw["obs_stats"]["mean"])[-1]), slots=config.env.slots,
        discrete=discrete, action_dim=int(np.shape(params["actor_head"]["kernel"])[-1]),
        normalize=config.algorithm.normalize_observations, others=others)


def stored_weights(raw: dict[str, Any]) -> ActorWeights:
    """The seed-batched acting weights of a checkpoint's raw runner state."""
    stats = raw["obs_stats"]
    mask = raw.get("obs_mask")
    as_array = lambda x: jnp.asarray(x)  # noqa: E731
    return ActorWeights(
        params=jax.tree.map(as_array, raw["params"]),
        obs_stats=RunningStats(mean=as_array(stats["mean"]), var=as_array(stats["var"]),
                               count=as_array(stats["count"])),
        obs_mask=None if mask is None else as_array(mask))


def load_checkpoint_policy(path: str | Path, env: Any = None, seed_index: int | None = None,
                deterministic: bool | None = None):
    """The trained actor of a checkpoint as an ``sgjax`` policy: actions sampled from it, or
    greedy with ``deterministic`` (default: the run's ``evaluation.deterministic``). The seed
    is ``seed_index``, else the one the checkpoint's meta names as best, else 0. Only the file
    is read (with ``env``, the environment it will act in, checked against)."""
    config, meta, raw = read(path)
    layout = actor_layout(path, config, meta, raw, env)
    if env is not None and env.observation_size != layout.obs_size:
        raise ValueError(f"{resolve(path)}: the policy reads observations of size "
                         f"{layout.obs_size}, this environment gives "
                         f"{env.observation_size}; build it with the checkpoint's settings "
                         "(sgjax evaluate does)")
    index = seed_index if seed_index is not None else int(meta.get("best_seed", 0))
    try:
        weights = stored_weights(raw).seed(index)
    except ValueError as err:
        raise ValueError(f"{resolve(path)}: {err}") from err
    if deterministic is None:
        deterministic = config.evaluation.deterministic
    return acting_policy(config.network, layout, weights, deterministic)


LOADER = register_loader(
    "checkpoint", matches=is_checkpoint, options=training_options, greedy=True,
    load=lambda spec, env, deterministic=None: load_checkpoint_policy(spec, env,
                                                           deterministic=deterministic))
