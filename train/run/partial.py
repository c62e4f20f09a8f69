"""A run's lanes kept in a file while they train, so that a killed run resumes where its last
save left it (``train.reproduce``'s cells, ``train.ablation``'s groups).

The file is a checkpoint (:mod:`train.run.checkpoint`): the config, a meta that names the lanes
and the updates done, and the lanes' state. A run that does not resume deletes a file it
finds; a resuming run reads it only when it was written for the same trained config
(:func:`train.algorithm.config.as_trained`) and the same lanes, else it stops with an error
naming the file.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp

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
