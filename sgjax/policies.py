"""Policies for evaluation and rendering: the built-in baselines and adapters.

A policy acts for one environment: ``policy(obs [R, D], key, state, params) -> actions`` (``[R]``
GO/STOP ints, or ``[R, d]`` floats in [-1, 1] for continuous actions); it must be jittable, and
the runners ``vmap`` it over environments. :func:`from_observations` adapts the common case of a
function of the observations alone, ``fn(obs, key) -> actions``.

Built-in baselines (:data:`BASELINES`):

* ``only_local``: always GO, the local planner alone (the paper's "Only Local" ablation);
* ``random``: uniformly random actions (GO/STOP with probability 1/2 each, or uniform in
  [-1, 1] per continuous dimension);
* ``stop_when_blocked``: GO, but STOP while a pedestrian, or another unfinished robot with a
  smaller index (a fixed priority, so two robots never wait for each other), is within
  ``STOP_DISTANCE`` m (body to body) and within ``STOP_HALF_ANGLE`` of the robot's heading.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import jax
import jax.numpy as jnp
from jax import Array

from sgjax.geometry import safe_norm

if TYPE_CHECKING:
    from sgjax.env import EnvParams, EnvState, SocialNavEnv

Policy = Callable[[Array, Array, "EnvState", "EnvParams"], Array]


@dataclasses.dataclass(frozen=True)
class RecurrentPolicy:
    """A policy with memory (a recurrent network): ``init(num_robots) -> carry`` at the start of
    an episode, then ``step(carry, obs, key, state, params) -> (carry, actions)``."""

    init: Callable[[int], Any]
    step: Callable[..., tuple[Any, Array]]

BASELINES = ("only_local", "random", "stop_when_blocked")
STOP_DISTANCE = 1.0  # m, body to body
STOP_HALF_ANGLE = math.pi / 3  # rad either side of the heading
GO, STOP = 0, 1


def only_local(env: SocialNavEnv) -> Policy:
    """Always GO: the local planner drives every robot."""
    _require_go_stop(env, "only_local")
    shape = (env.max_agents,)
    return lambda obs, key, state, params: jnp.zeros(shape, jnp.int32)


def random_policy(env: SocialNavEnv) -> Policy:
    """Uniformly random actions in the environment's action space."""
    if env.config.action_mode == "go_stop":
        shape = (env.max_agents,)
        return lambda obs, key, state, params: jax.random.bernoulli(key, 0.5, shape).astype(
            jnp.int32)
    shape = (env.max_agents, env.config.action_dim)
    return lambda obs, key, state, params: jax.random.uniform(key, shape, minval=-1.0,
                                                              maxval=1.0)


def stop_when_blocked(env: SocialNavEnv, distance: float = STOP_DISTANCE,
                      half_angle: float = STOP_HALF_ANGLE) -> Policy:
    """GO unless a pedestrian or a robot of higher priority (smaller index) is close ahead."""
    _require_go_stop(env, "stop_when_blocked")
    cos_limit = math.cos(half_angle)

    def blocked_by(x: Array, y: Array, heading: Array, radius: Array, ox: Array, oy: Array,
                   oradius: Array, candidate: Array) -> Array:
        dx, dy = ox[None, :] - x[:, None], oy[None, :] - y[:, None]
        centre = safe_norm(dx, dy)
        ahead = (dx * jnp.cos(heading)[:, None] + dy * jnp.sin(heading)[:, None]
                 >= cos_limit * centre)
        close = centre - radius[:, None] - oradius[None, :] < distance
        return jnp.any(candidate & ahead & close, axis=1)

    def policy(obs: Array, key: Array, state: EnvState, params: EnvParams) -> Array:
        r, h = state.robots, state.humans
        radius = params.robots.radius
        index = jnp.arange(r.x.shape[0])
        higher = r.active[None, :] & (index[None, :] < index[:, None])
        stop = blocked_by(r.x, r.y, r.heading, radius, r.x, r.y, radius, higher)
        if h.x.shape[0]:
            human_radius = jnp.broadcast_to(params.humans.radius, h.x.shape)
            stop = stop | blocked_by(r.x, r.y, r.heading, radius, h.x, h.y, human_radius,
                                     h.active[None, :])
        return jnp.where(stop, STOP, GO).astype(jnp.int32)

    return policy


def from_observations(fn: Callable[[Array, Array], Array]) -> Policy:
    """A policy from ``fn(obs [R, D], key) -> actions`` (a trained network, say)."""
    return lambda obs, key, state, params: fn(obs, key)


def _require_go_stop(env: SocialNavEnv, name: str) -> None:
    if env.config.action_mode != "go_stop":
        raise ValueError(f"policy {name!r} chooses GO/STOP and needs action_mode 'go_stop'; "
                         f"this environment has {env.config.action_mode!r} (try 'random')")


_BUILDERS = {"only_local": only_local, "random": random_policy,
             "stop_when_blocked": stop_when_blocked}


def load_policy(spec: str | Policy | RecurrentPolicy, env: SocialNavEnv
                ) -> Policy | RecurrentPolicy:
    """A policy for ``env`` from a baseline name, ``"package.module:function"`` naming a
    function ``fn(obs, key) -> actions``, a trainer checkpoint (a ``.msgpack`` file or a run
    folder, see ``train.checkpoint``), or a policy (returned as is)."""
    if callable(spec) or isinstance(spec, RecurrentPolicy):
        return spec
    if is_checkpoint(spec):
        from train.checkpoint import load_policy as load_checkpoint_policy

        return load_checkpoint_policy(spec, env)
    if spec in _BUILDERS:
        return _BUILDERS[spec](env)
    if ":" in spec:
        module_name, _, attr = spec.partition(":")
        try:
            module = importlib.import_module(module_name)
        except ImportError as err:
            raise ValueError(f"policy {spec!r}: cannot import module {module_name!r} ({err})"
                             ) from err
        fn = getattr(module, attr, None)
        if not callable(fn):
            raise ValueError(f"policy {spec!r}: module {module_name!r} has no function {attr!r}")
        return from_observations(fn)
    raise ValueError(f"policy {spec!r} is not known: use a baseline ({', '.join(BASELINES)}), "
                     "'package.module:function' for a function (obs, key) -> actions, or a "
                     "trainer checkpoint (.msgpack file or run folder)")


def is_checkpoint(spec: Any) -> bool:
    """Whether ``spec`` names a trainer checkpoint file or run folder."""
    from pathlib import Path

    if not isinstance(spec, str) or spec in _BUILDERS:
        return False
    path = Path(spec)
    return path.suffix == ".msgpack" or (path.is_dir() and (
        (path / "checkpoints").is_dir() or any(path.glob("*.msgpack"))))


def checkpoint_make_kwargs(spec: Any) -> dict[str, Any]:
    """The ``sgjax.make`` settings a checkpoint was trained with ({} for other policies)."""
    if not is_checkpoint(spec):
        return {}
    from train.checkpoint import make_kwargs

    return make_kwargs(spec)
