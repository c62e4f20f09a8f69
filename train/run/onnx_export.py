"""A trained actor as an ONNX file (``python -m train.export RUN --format onnx``), for a robot
that runs it with onnxruntime and knows nothing of JAX, sgjax or the trainer (issue 69).

The file holds one seed's greedy decision as a pure function of the observation: the
observation mask and the running normalisation statistics folded in (constants of the graph),
the network, and the head. Inputs and outputs, ``B`` robots (a dynamic dimension; for a recurrent
network or one with a one-hot robot id, exactly the robot slots it was trained with: the
sidecar's ``network.rows``, absent robots' rows zeros):

* ``observation [B, D]`` float32: each robot's observation, laid out as the sidecar's
  ``observation.terms`` say;
* ``memory [B, C]`` float32 (recurrent networks only): the recurrent state the previous call
  returned, zeros at an episode's start;
* ``logits [B, 2]`` (GO/STOP) or ``mean [B, A]`` (continuous, in [-1, 1]): the head;
* ``action [B]`` int32 (GO/STOP: 0 GO, 1 STOP, the most likely) or ``[B, A]`` float32 (the
  mean, clipped to [-1, 1]);
* ``memory_out [B, C]`` (recurrent networks only): the state to pass back next call.

The conversion is jax2onnx's (it traces the JAX function and writes the ONNX graph: the
well-kept converter, rather than a hand-written graph per network kind). A JSON sidecar beside
the file names the observation layout, the action meaning and the provenance
(:func:`sidecar`)."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from sgjax.dynamics.limits import ACKERMANN, MODEL_NAMES
from sgjax.environment.registry import make
from sgjax.evaluation.provenance import provenance
from sgjax.files import write_atomic
from sgjax.types import GO, STOP
from train.algorithm.actor import ActorLayout, ActorWeights, actor_features
from train.algorithm.config import NetworkConfig, TrainConfig
from train.algorithm.networks import ActorCritic, carry_size, greedy
from train.run.checkpoint import actor_layout, read, resolve, stored_weights

SIDECAR_SCHEMA = "sgjax.onnx_actor/1"


def decision_function(network: NetworkConfig, layout: ActorLayout, weights: ActorWeights
                      ) -> Callable[..., tuple[jax.Array, ...]]:
    """The greedy decision of one seed's ``weights`` as ``f(observation [B, D][, memory [B,
    C]]) -> (head [B, .], action [B] or [B, A][, memory_out [B, C]])``."""
    model = ActorCritic(network, layout.action_dim, layout.discrete, layout.others)

    def decide(observation: jax.Array, memory: jax.Array | None = None) -> tuple:
        obs = observation if weights.obs_mask is None else observation * weights.obs_mask
        x = actor_features(network, layout, weights.obs_stats, obs)
        carry = memory if memory is not None else jnp.zeros((obs.shape[0], 1), jnp.float32)
        starts = jnp.zeros((1, obs.shape[0]), bool)
        carry, out = model.apply(weights.params, carry, x[None], starts,
                                 method=ActorCritic.act)
        head = out[0]
        action = (greedy(head, True) if layout.discrete else jnp.clip(head, -1.0, 1.0))
        return (head, action, carry) if memory is not None else (head, action)

    return decide


def _as_traced(fn: Callable[..., tuple], shapes: list[Any]) -> Callable[..., tuple]:
    """``fn`` as its jaxpr at the concrete ``shapes`` (float32), evaluated: flax's ``nn.scan``
    computes its length from the inputs' shapes, which the converter's tracer does not give
    it; the recorded ``scan`` keeps its length (and the rows their count: a recurrent actor
    takes exactly its robot slots, symbolic batch sizes failing inside the recurrent cell)."""
    closed = jax.make_jaxpr(fn)(*(jax.ShapeDtypeStruct(s, jnp.float32) for s in shapes))

    def traced(*args: jax.Array) -> tuple:
        return tuple(jax.core.eval_jaxpr(closed.jaxpr, closed.consts, *args))

    return traced


def load_actor(run: str | Path, seed_index: int | None = None
               ) -> tuple[Path, TrainConfig, ActorLayout, ActorWeights, int]:
    """``(checkpoint, config, layout, one seed's weights, that seed's index)`` of a run folder
    or checkpoint file (the seed the checkpoint names as best unless ``seed_index``)."""
    path = resolve(run)
    config, meta, raw = read(path)
    layout = actor_layout(path, config, meta, raw)
    index = seed_index if seed_index is not None else int(meta.get("best_seed", 0))
    try:
        weights = stored_weights(raw).seed(index)
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from err
    return path, config, layout, weights, index


def export_onnx(run: str | Path, out: str | Path, seed_index: int | None = None
                ) -> tuple[Path, Path]:
    """Write the actor of ``run`` as ``out`` (ONNX) and its sidecar ``out`` with ``.json``;
    returns both paths."""
    from jax2onnx import to_onnx  # the export extra: pip install -e '.[export]'

    path, config, layout, weights, index = load_actor(run, seed_index)
    network = config.network
    decide = decision_function(network, layout, weights)
    rows: Any = layout.slots if network.agent_id or network.recurrent else "B"
    inputs: list[Any] = [(rows, layout.obs_size)]
    names_in, names_out = ["observation"], ["logits" if layout.discrete else "mean", "action"]
    if network.recurrent:
        inputs.append((rows, carry_size(network)))
        names_in.append("memory")
        names_out.append("memory_out")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    if network.recurrent:  # flax's scan over time is traced once, at the concrete shapes
        decide = _as_traced(decide, inputs)
    to_onnx(decide, inputs, model_name="sgjax_actor", return_mode="file",
            output_path=str(out), input_names=names_in, output_names=names_out)
    note = sidecar(path, config, layout, index, names_in, names_out)
    side = write_atomic(out.with_suffix(".json"), json.dumps(note, indent=1) + "\n")
    return out, side


def sidecar(path: Path, config: TrainConfig, layout: ActorLayout, seed_index: int,
            inputs: list[str], outputs: list[str]) -> dict[str, Any]:
    """What a robot needs beside the graph: the observation layout (each term's columns, from
    an environment built with the run's settings), the action meaning, the inputs and outputs,
    and the provenance (the checkpoint's hash, the seed, the run's configuration)."""
    options = config.env.options
    env, params = make(config.env.scenarios[0], options=options,
                       num_agents=config.env.curriculum[0][1], max_agents=config.env.slots)
    spans = env.config.observer.columns(env.config.layout).terms
    terms = [{"name": name, "start": start, "stop": start + columns.size,
              "columns": list(columns.names), "options": term_options(term)}
             for (name, start, columns), term in zip(spans, env.config.observer.terms,
                                                     strict=True)]
    action = ({"kind": "go_stop", "values": {str(GO): "GO", str(STOP): "STOP"},
               "meaning": "GO follows the local planner toward the next waypoint; STOP brakes"}
              if layout.discrete else
              {"kind": "continuous", "size": layout.action_dim, "range": [-1.0, 1.0],
               "meaning": "normalised commands, scaled by the robot's limits (docs/robots.md)"})
    return {
        "schema": SIDECAR_SCHEMA,
        "inputs": inputs, "outputs": outputs,
        "observation": {"size": layout.obs_size, "preset": options.terms.observation_preset,
                        "terms": terms, "dt": options.physics.dt},
        "action": action,
        "robots": robot_limits(params.robots),
        "humans": {"radius": float(np.asarray(params.humans.radius))},
        "network": {"kind": config.network.kind, "agent_id": config.network.agent_id,
                    "robot_slots": layout.slots,
                    "rows": layout.slots if config.network.agent_id or config.network.recurrent
                    else "any",
                    "memory": carry_size(config.network) if config.network.recurrent
                    else 0},
        "checkpoint": {"path": str(path), "sha256": hashlib.sha256(
            path.read_bytes()).hexdigest(), "seed_index": seed_index},
        "trained_on": list(config.env.scenarios),
        "provenance": provenance(config=config.to_dict()),
    }


def term_options(term: Any) -> dict[str, Any]:
    """An observation term's settings (its dataclass fields) as JSON values."""
    return {field.name: (list(value) if isinstance(value, tuple) else value)
            for field in dataclasses.fields(term)
            for value in [getattr(term, field.name)]}


def robot_limits(robots: Any) -> list[dict[str, Any]]:
    """Each robot slot's kind and limits (SI units: m, m/s, rad/s, rad) as the environment the
    actor was exported from sets them: what a robot-side node needs to turn continuous actions
    into velocity commands and to read the others' radii."""
    kind = {code: name for name, code in MODEL_NAMES.items()}
    fields = ("radius", "max_speed", "max_reverse_speed", "max_omega", "wheelbase",
              "min_turn_radius")
    values = {name: np.asarray(getattr(robots, name), np.float64) for name in fields}
    steering = np.asarray(robots.max_steering, np.float64)
    return [{"model": kind[int(code)], **{name: float(values[name][i]) for name in fields},
             "max_steering": float(steering[i]) if int(code) == ACKERMANN else 0.0}
            for i, code in enumerate(np.asarray(robots.model))]


class OnnxActor:
    """An exported actor run by onnxruntime on the CPU: ``actor(observations [B, D][,
    memory])`` returns its outputs as numpy arrays (the module doc's order)."""

    def __init__(self, model_path: str | Path):
        import onnxruntime as ort

        self.session = ort.InferenceSession(str(model_path),
                                            providers=["CPUExecutionProvider"])

    def __call__(self, observations: np.ndarray, memory: np.ndarray | None = None
                 ) -> list[np.ndarray]:
        feed = {"observation": np.asarray(observations, np.float32)}
        if memory is not None:
            feed["memory"] = np.asarray(memory, np.float32)
        return self.session.run(None, feed)
