"""The one term contract: every observation term, reward term and episode ender is called as
``term(inputs)`` with the same :class:`TermInput` and returns its own kind of output.

* observation term (``sgjax.observations.ObservationTerm``): ``[R, size]`` float, with
  ``size(layout)`` columns named by ``columns(layout)``;
* reward term (``sgjax.rewards.RewardTerm``): ``[R]`` float, natural sign (penalties < 0);
* episode ender (``sgjax.terms.enders.Ender``): an ``Outcome`` (``[R]`` terminated,
  truncated, reward).

A term is a frozen dataclass whose fields are its options (static: changing one recompiles)
and a registered ``name``; it is written for one episode (``R`` robot slots) and batched from
outside with ``vmap``. ``docs/terms.md`` shows how to write one.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

from flax import struct
from jax import Array

from sgjax.types import EnvParams, EnvState, Layout


@struct.dataclass
class TermInput:
    """What every term reads, for one episode (a pytree; ``layout`` is static).

    * ``prev``, ``state``: the state before and after the step. Rewards see the state after the
      enders have spoken (absorbing robots already marked), enders the state just before.
      Observation terms observe one state: ``prev`` is ``state`` (their past is in
      ``state.history``), so an observation depends on the state alone
      (:meth:`TermInput.observing`).
    * ``actions``: the actions in force during the step, ``[R]`` int32 GO(0)/STOP(1) or
      ``[R, A]`` float32 in [-1, 1] (``layout.action_mode``); for observation terms the action
      in force in ``state`` (``state.held_action``).
    * ``params``: the environment's params (limits, map, weights, dt ...).
    * ``key``: a PRNG key for terms that draw random numbers (``needs_key``); each such term
      gets its own key. Unused keys cost nothing.
    * ``layout``: the static sizes (``R = layout.max_agents``, ``H``, ``Z``, action mode).
    """

    prev: EnvState
    state: EnvState
    actions: Array
    params: EnvParams
    key: Array
    layout: Layout = struct.field(pytree_node=False)

    @classmethod
    def observing(cls, state: EnvState, params: EnvParams, layout: Layout, key: Array
                  ) -> TermInput:
        """The input of observation terms for ``state``: ``prev`` is ``state`` and the actions
        are the ones in force (``state.held_action``)."""
        return cls(prev=state, state=state, actions=state.held_action, params=params, key=key,
                   layout=layout)


@dataclasses.dataclass(frozen=True)
class Term:
    """Base of every term: a frozen dataclass of options with a registered ``name``.

    Subclasses set ``name`` and implement ``__call__(inputs: TermInput)``; the kind's base
    class (``ObservationTerm``, ``RewardTerm``, ``Ender``) fixes what the call returns. Class
    flags: ``needs_key`` (draws random numbers from ``inputs.key``), ``uses_zones`` (reads
    ``state.zones``, so the environment keeps the conflict-zone books).
    """

    name: ClassVar[str] = ""
    needs_key: ClassVar[bool] = False
    uses_zones: ClassVar[bool] = False

    def __call__(self, inputs: TermInput) -> Any:
        raise NotImplementedError
