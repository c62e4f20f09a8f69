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
  ``STOP_DISTANCE`` m (body to body) and within ``STOP_HALF_ANGLE`` of the robot's heading;
* ``orca``, ``dwa``, ``social_force`` (continuous actions; :mod:`sgjax.evaluation.controllers`):
ORCA
  velocities, the dynamic window approach, and the pedestrians' social forces, each toward the
  robot's route under its kinematic limits; :func:`policy_options` asks for
  ``action_mode="continuous"``.

Other policies come from *loaders* (:class:`PolicyLoader`): each recognises the specs it reads
(a trainer checkpoint, say) and builds the policy for an environment. Loaders register with
:func:`register_loader`, or are found at first use in the ``sgjax.policy_loaders`` entry point
group (the trainer ships ``checkpoint = "train.run.checkpoint:LOADER"``), so this module never
imports the packages that provide them.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import re
from collections.abc import Callable
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

import jax
import jax.numpy as jnp
from jax import Array

from sgjax.environment.options import MakeOptions
from sgjax.evaluation.controllers import dwa_controller, orca_controller, social_force_controller
from sgjax.kernels.geometry import safe_norm
from sgjax.types import GO, STOP

if TYPE_CHECKING:
    from sgjax.environment.env import SocialNavEnv
    from sgjax.types import EnvParams, EnvState

Policy = Callable[[Array, Array, "EnvState", "EnvParams"], Array]


@dataclasses.dataclass(frozen=True)
class RecurrentPolicy:
    """A policy with memory (a recurrent network): ``init(num_robots) -> carry`` at the start of
    an episode, then ``step(carry, obs, key, state, params) -> (carry, actions)``."""

    init: Callable[[int], Any]
    step: Callable[..., tuple[Any, Array]]

BASELINES = ("only_local", "random", "stop_when_blocked", "orca", "dwa", "social_force")
# Baselines that command velocities: the environment they act in has continuous actions.
CONTINUOUS_BASELINES = ("orca", "dwa", "social_force")
STOP_DISTANCE = 1.0  # m, body to body
STOP_HALF_ANGLE = math.pi / 3  # rad either side of the heading


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
    """GO unless a pedestrian, a robot of higher priority (smaller index) or a robot settling on
    its goal is close ahead."""
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
        # a robot settling on its goal yields to nobody: wait for it whatever its index
        higher = (r.active[None, :] & (index[None, :] < index[:, None])) | r.settling[None, :]
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
             "stop_when_blocked": stop_when_blocked, "orca": orca_controller,
             "dwa": dwa_controller, "social_force": social_force_controller}


LOADER_GROUP = "sgjax.policy_loaders"
_FUNCTION_SPEC = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_]\w*$")


@dataclasses.dataclass(frozen=True)
class PolicyLoader:
    """Policies from specs that are neither baselines nor ``module:function``: ``matches(spec)``
    says whether this loader reads ``spec``; ``load(spec, env)`` builds the policy for ``env``
    (``env`` may be None); ``options(spec)`` gives the :func:`sgjax.make` options the policy
    acts in (a checkpoint's: the settings it was trained with), a
    :class:`~sgjax.environment.options.MakeOptions` (robot counts aside: the evaluation sets
    them). ``greedy`` says that ``load`` takes ``deterministic=True | False`` (the most likely
    action every step, or actions sampled from the policy)."""

    name: str
    matches: Callable[[str], bool]
    load: Callable[..., Policy | RecurrentPolicy]
    options: Callable[[str], MakeOptions] = lambda spec: MakeOptions()
    greedy: bool = False


_LOADERS: dict[str, PolicyLoader] = {}
_discovery: list[str] | None = None  # None until the entry points are read; then their errors


def register_loader(name: str | PolicyLoader, matches: Callable[[str], bool] | None = None,
                    load: Callable[..., Policy | RecurrentPolicy] | None = None,
                    options: Callable[[str], MakeOptions] | None = None,
                    greedy: bool = False) -> PolicyLoader:
    """Register a policy loader (a :class:`PolicyLoader`, or its name and functions); a loader
    of the same name is replaced. Returns the loader."""
    if isinstance(name, PolicyLoader):
        loader = name
    else:
        if matches is None or load is None:
            raise TypeError("register_loader: give a PolicyLoader, or a name with matches and "
                            "load functions")
        loader = PolicyLoader(name, matches, load, options or (lambda spec: MakeOptions()),
                              greedy)
    _LOADERS[loader.name] = loader
    return loader


def registered_loaders() -> dict[str, PolicyLoader]:
    """Every policy loader, the entry point group's included, by name."""
    _discover()
    return dict(_LOADERS)


def _discover() -> list[str]:
    """Load the ``sgjax.policy_loaders`` entry points once; returns the problems met."""
    global _discovery
    if _discovery is None:
        problems = []
        for point in metadata.entry_points(group=LOADER_GROUP):
            try:
                loader = point.load()
            except Exception as err:  # a broken plug-in must not break the baselines
                problems.append(f"entry point {point.name} = {point.value!r}: {err!r}")
                continue
            if not isinstance(loader, PolicyLoader):
                problems.append(f"entry point {point.name} = {point.value!r} is not a "
                                "sgjax.evaluation.policies.PolicyLoader")
                continue
            _LOADERS.setdefault(loader.name, loader)
        _discovery = problems
    return _discovery


def find_loader(spec: Any) -> PolicyLoader | None:
    """The loader that reads ``spec`` (a string that is not a baseline), if any."""
    if not isinstance(spec, str) or spec in _BUILDERS:
        return None
    for attempt in range(2):
        if attempt:
            _discover()
        for loader in list(_LOADERS.values()):
            if loader.matches(spec):
                return loader
    return None


def load_policy(spec: str | Policy | RecurrentPolicy, env: SocialNavEnv,
                deterministic: bool | None = None) -> Policy | RecurrentPolicy:
    """A policy for ``env`` from a baseline name, ``"package.module:function"`` naming a
    function ``fn(obs, key) -> actions``, a spec a registered loader reads (a trainer
    checkpoint: a ``.msgpack`` file or a run folder, see ``train.run.checkpoint``), or a policy
    (returned as is).

    ``deterministic`` (True: the most likely action every step; False: sampled; None: the
    loader's default, for a checkpoint its run's ``evaluation.deterministic``) is passed to a
    loader that reads stochastic policies (``PolicyLoader.greedy``); a loader that does not
    take it is an error naming it. Baselines, functions and policy objects act as they are
    written and ignore it."""
    if callable(spec) or isinstance(spec, RecurrentPolicy):
        return spec
    if spec in _BUILDERS:
        return _BUILDERS[spec](env)
    if _FUNCTION_SPEC.match(spec):
        return _function_policy(spec)
    loader = find_loader(spec)
    if loader is not None:
        if deterministic is None:
            return loader.load(spec, env)
        if not loader.greedy:
            raise ValueError(f"policy {spec!r}: its loader {loader.name!r} cannot choose "
                             "between greedy and sampled actions (deterministic="
                             f"{deterministic}); load it without that choice")
        return loader.load(spec, env, deterministic=deterministic)
    if spec.endswith(".msgpack") or Path(spec).exists():
        problems = "".join(f"; {p}" for p in _discover())
        raise ValueError(
            f"policy {spec!r} looks like a trainer checkpoint, but no installed policy loader "
            f"reads it (loaders: {sorted(_LOADERS) or 'none'}{problems}). Install the trainer, "
            "pip install 'sgjax[train]' (from a checkout: pip install -e '.[train]'), which "
            f"registers its loader in the {LOADER_GROUP!r} entry point group, or import "
            "train.run.checkpoint before evaluating")
    raise ValueError(f"policy {spec!r} is not known: use a baseline ({', '.join(BASELINES)}), "
                     "'package.module:function' for a function (obs, key) -> actions, or a "
                     "trainer checkpoint (.msgpack file or run folder)")


def _function_policy(spec: str) -> Policy:
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


def policy_options(spec: Any) -> MakeOptions:
    """The :func:`sgjax.make` options a policy spec acts in: continuous actions for the
    velocity baselines (``orca``, ``dwa``, ``social_force``), a checkpoint's settings from
    training (through its loader), else the defaults. Robot counts are left at their defaults
    (the evaluation sets them)."""
    if spec in CONTINUOUS_BASELINES:
        return MakeOptions.from_keywords(f"policy {spec!r}", action_mode="continuous")
    if not isinstance(spec, str) or _FUNCTION_SPEC.match(spec):
        return MakeOptions()
    loader = find_loader(spec)
    if loader is None:
        return MakeOptions()
    options = loader.options(spec)
    if not isinstance(options, MakeOptions):
        raise TypeError(f"policy {spec!r}: its loader {loader.name!r} gave {options!r}, not "
                        "the MakeOptions (sgjax.environment.options) it acts in")
    return options
