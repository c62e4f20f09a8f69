"""A run's lanes kept in a file while they train, so that a killed run resumes where its last
save left it (``train.reproduce``'s cells, ``train.ablation``'s groups); and values computed
piece by piece (:class:`PartialValues`: a cell's evaluation, robot count by robot count).

The file is a checkpoint (:mod:`train.run.checkpoint`): the config, a meta that names the lanes
and the updates done, and the lanes' state. A run that does not resume deletes a file it
finds; a resuming run reads it only when it was written for the same trained config
(:func:`train.algorithm.config.as_trained`) and the same lanes, else it stops with an error
naming the file.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from sgjax.files import write_atomic
from train.algorithm.config import TrainConfig, as_trained
from train.run import checkpoint

SAVES_PER_RUN = 10  # a run's lanes are saved about this many times while they train


def shaped_like(template: Any) -> Callable[[dict], Any]:
    """A ``restore`` for :meth:`PartialFile.load`: the raw state in ``template``'s shapes (a
    ``jax.eval_shape`` tree), as arrays."""
    def restore(raw: dict) -> Any:
        return jax.tree.map(jnp.asarray, checkpoint.state_from_raw(template, raw))
    return restore


class PartialFile:
    """The partial file of one run of lanes (``path`` None: no file, nothing kept)."""

    def __init__(self, path: Path | None, config: TrainConfig, what: str,
                 meta: dict[str, Any] | None = None, resume: bool = False,
                 saves: int = SAVES_PER_RUN):
        """``what`` names the run in errors ("cell", "group"); ``meta``: what else must agree
        for a resume (the lanes, the calls); a run without ``resume`` deletes a file it
        finds."""
        self.path, self.config, self.what = path, config, what
        self.meta, self.saves = dict(meta or {}), saves
        if path is not None and path.is_file() and not resume:
            path.unlink()

    def load(self, restore: Callable[[dict], Any]) -> tuple[Any, int] | None:
        """``(state, updates done)`` from the file, the state made by ``restore`` from the
        file's raw state dict (:func:`shaped_like`), or None when there is no file."""
        if self.path is None or not self.path.is_file():
            return None
        config, saved, raw = checkpoint.read(self.path)
        same = {key: saved.get(key) for key in self.meta} == self.meta
        if not same or as_trained(config.to_dict()) != as_trained(self.config.to_dict()):
            raise ValueError(f"{self.path}: a partly trained {self.what} of other lanes or "
                             f"another configuration; delete it to train this {self.what} "
                             "afresh")
        try:
            state = restore(raw)
        except (KeyError, ValueError, TypeError) as err:
            raise ValueError(f"{self.path}: does not fit this {self.what}'s lanes ({err}); "
                             f"delete it to train this {self.what} afresh") from err
        return state, int(saved["updates"])

    def save_if_due(self, state: Any, done: int, per_call: int, total: int) -> None:
        """Save ``state`` after the call that brought the run to ``done`` of ``total``
        updates, if it is one of the about :attr:`saves` saves
        (:func:`train.run.checkpoint.checkpoint_due`; atomically)."""
        if self.path is not None and checkpoint.checkpoint_due(done, per_call, total,
                                                               self.saves):
            checkpoint.save(self.path, self.config, state,
                            {**self.meta, "updates": done, "of": total})


class PartialValues:
    """Values a run computes piece by piece (``train.reproduce``'s evaluation of a cell, one
    robot count after another: hours at SocialGym's 40 Hz), kept in a JSON file after each
    piece, so that a killed run plays only the pieces it had not finished.

    ``identity`` (JSON-able) is what the values depend on beyond the run's settings, which the
    caller's resume already checks: the evaluated weights' hash (:func:`weights_hash`). A file
    made for another identity (the cell trained again) is not used: it is replaced, and
    ``log`` says so. A run that does not resume deletes a file it finds; ``path`` None keeps
    nothing."""

    def __init__(self, path: Path | None, identity: Any, resume: bool,
                 log: Callable[[str], None] = print):
        self.path, self.identity = path, identity
        self.values: dict[str, Any] = {}
        if path is None or not path.is_file():
            return
        if not resume:
            path.unlink()
            return
        try:
            data = json.loads(path.read_text())
            kept, values = data["identity"], data["values"]
        except (ValueError, KeyError, TypeError) as err:
            raise ValueError(f"{path}: not a file of partial values ({err}); delete it to "
                             "compute them afresh") from None
        if kept != identity:
            log(f"    {path}: made for other weights or settings, not used")
            return
        self.values = dict(values)
        log(f"    {path}: {len(self.values)} piece(s) kept ({', '.join(self.values)})")

    def get(self, piece: str) -> Any | None:
        """The value of ``piece`` kept from an earlier run, or None."""
        return self.values.get(piece)

    def put(self, piece: str, value: Any) -> None:
        """Keep ``value`` (JSON-able) for ``piece`` and write the file (atomically)."""
        self.values[piece] = value
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(self.path, json.dumps({"identity": self.identity,
                                                "values": self.values}) + "\n")


def weights_hash(tree: Any) -> str:
    """sha256 (hex) of every leaf of a pytree of arrays (its bytes, shapes and dtypes, in
    tree order): the identity of a run's evaluated weights."""
    digest = hashlib.sha256()
    for leaf in jax.tree.leaves(tree):
        array = np.asarray(leaf)
        digest.update(f"{array.shape}{array.dtype.str}".encode())
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()
