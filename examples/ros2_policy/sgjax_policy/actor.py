"""The exported actor run by onnxruntime, with its memory (recurrent networks) kept between
control ticks and its rows laid out as the sidecar says."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

GO, STOP = 0, 1  # the GO/STOP head's actions (actor.json: action.values)


class OnnxPolicy:
    """``OnnxPolicy("actor.onnx")`` (``actor.json`` beside it): :meth:`decide` maps one
    observation row per robot ``[n, D]`` to one action per robot (``[n]`` int GO/STOP, or
    ``[n, A]`` continuous in [-1, 1]).

    A recurrent network's memory is carried here from tick to tick (:meth:`start` clears it at
    an episode's start); a network with fixed rows (recurrent, or with robot ids) gets exactly
    its trained robot slots, the rows past ``n`` zeros, as in training."""

    def __init__(self, model: str | Path, threads: int = 1):
        import onnxruntime as ort

        model = Path(model)
        sidecar = model.with_suffix(".json")
        if not sidecar.is_file():
            raise FileNotFoundError(f"{sidecar}: the actor's sidecar (written beside the .onnx "
                                    "by python -m train.export) is missing")
        self.sidecar: dict[str, Any] = json.loads(sidecar.read_text())
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads
        self.session = ort.InferenceSession(str(model), options,
                                            providers=["CPUExecutionProvider"])
        network = self.sidecar["network"]
        self.rows = None if network["rows"] == "any" else int(network["rows"])
        self.memory_size = int(network["memory"])
        self.size = int(self.sidecar["observation"]["size"])
        self.discrete = self.sidecar["action"]["kind"] == "go_stop"
        self.memory: np.ndarray | None = None
        self.start()

    def start(self) -> None:
        """An episode starts: a recurrent network's memory back to zeros."""
        self.memory = (np.zeros((self.rows, self.memory_size), np.float32)
                       if self.memory_size else None)

    def decide(self, observations: np.ndarray) -> np.ndarray:
        """Actions of the ``n`` robots whose observation rows ``[n, D]`` are given."""
        obs = np.asarray(observations, np.float32)
        if obs.ndim != 2 or obs.shape[1] != self.size:
            raise ValueError(f"observations must be [robots, {self.size}], got {obs.shape}")
        count = obs.shape[0]
        if self.rows is not None:
            if count > self.rows:
                raise ValueError(f"the actor was trained with {self.rows} robot slots; "
                                 f"{count} robots cannot share it")
            obs = np.concatenate([obs, np.zeros((self.rows - count, self.size), np.float32)])
        feed = {"observation": obs}
        if self.memory is not None:
            feed["memory"] = self.memory
        outputs = self.session.run(None, feed)
        if self.memory is not None:
            self.memory = outputs[2]
        return outputs[1][:count]
