"""SocialGym 2.0's conflict-zone order rewards (Any Order and Enforced Order)."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import jax.numpy as jnp
from jax import Array

from sgjax.kernels import zone_books as zn
from sgjax.rewards.base import REWARDS, RewardTerm
from sgjax.validation import check_bool

if TYPE_CHECKING:
    from sgjax.terms.contract import TermInput


@REWARDS.register
@dataclasses.dataclass(frozen=True)
class ZoneOrder(RewardTerm):
    """Summed over the map's zones, per robot. A robot is *in turn* when its place in the queue
    equals its assigned priority (both read before the step; see :mod:`sgjax.kernels.zone_books`).

    Event mode (default): entering in turn, or entering at all with ``any_order``, gives +1, or
    -1 instead with ``multiple_entry_penalty`` when more than one robot is on the zone's edge on
    its way in; exiting out of turn gives -1 with ``incorrect_penalty`` (not with
    ``any_order``); anything else 0. ``continuous`` (SocialGym's weak out-of-zone signal)
    instead pays, every step while still to pass, +1 in turn / -1 out of turn inside the zone
    and +0.1 / -0.1 outside. Presets: ``any_order`` and ``enforced_order``.
    """

    name = "zone_order"
    uses_zones = True
    any_order: bool = False
    incorrect_penalty: bool = True
    multiple_entry_penalty: bool = True
    continuous: bool = False

    def __post_init__(self) -> None:
        for field in ("any_order", "incorrect_penalty", "multiple_entry_penalty", "continuous"):
            check_bool(field, getattr(self, field))

    def __call__(self, inputs: TermInput) -> Array:
        prev, state, params, layout = inputs.prev, inputs.state, inputs.params, inputs.layout
        if layout.num_zones == 0:
            return jnp.zeros(layout.max_agents)
        rect, radius = params.map.zone_rect, params.robots.radius
        before, after = prev.zones, state.zones
        in_turn = zn.priority_rank(before) == zn.current_rank(before, prev.robots.x,
                                                              prev.robots.y, rect)
        in_turn = in_turn & zn.waiting(before)
        if self.continuous:
            inside = before.phase == zn.INSIDE
            scale = jnp.where(inside, 1.0, 0.1)
            value = jnp.where(in_turn, scale, -scale) * zn.waiting(before)
            return jnp.sum(value, axis=1)
        entered = (before.phase == zn.BEFORE) & (after.phase == zn.INSIDE)
        exited = (before.phase == zn.INSIDE) & (after.phase == zn.LEFT)
        entering, _ = zn.straddling(after, state.robots.x, state.robots.y, radius, rect)
        crowded = jnp.sum(entering, axis=0, keepdims=True) > 1
        good_entry = entered & (in_turn | self.any_order)
        entry = jnp.where(crowded & self.multiple_entry_penalty, -1.0, 1.0) * good_entry
        bad_exit = exited & ~in_turn & self.incorrect_penalty & (not self.any_order)
        return jnp.sum(entry - bad_exit.astype(jnp.float32), axis=1)
