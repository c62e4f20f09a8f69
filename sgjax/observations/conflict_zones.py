"""Conflict-zone observation terms (SocialGym 2.0's zone observations), one value per zone of
the map (size ``Z``, one block per zone; see :mod:`sgjax.kernels.zone_books` for the
definitions)."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, ClassVar

import jax.numpy as jnp
from jax import Array

from sgjax.kernels import zone_books as zn
from sgjax.observations.base import OBSERVATIONS, ObservationTerm
from sgjax.observations.columns import Columns

if TYPE_CHECKING:
    from sgjax.terms.contract import TermInput
    from sgjax.types import Layout


@dataclasses.dataclass(frozen=True)
class ZoneTerm(ObservationTerm):
    """Base of the zone terms: ``value(zones, x, y, radius, rect) -> [R, Z]``, one column per
    zone named ``column[z]``."""

    uses_zones = True
    column: ClassVar[str] = "value"

    def columns(self, layout: Layout) -> Columns:
        return Columns.plain(self.column, repeat=layout.num_zones)

    def __call__(self, inputs: TermInput) -> Array:
        state, params = inputs.state, inputs.params
        r = state.robots
        return self.value(state.zones, r.x, r.y, params.robots.radius,
                          params.map.zone_rect).astype(jnp.float32)

    def value(self, zones: zn.ZoneState, x: Array, y: Array, radius: Array, rect: Array
              ) -> Array:
        raise NotImplementedError


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class ZonePriority(ZoneTerm):
    """Assigned turn among the robots still to pass (0 = due now); -1 after leaving or for
    robots whose route avoids the zone."""

    name = "zone_priority"
    column = "priority"

    def value(self, zones, x, y, radius, rect):  # noqa: ANN001, ANN201
        return zn.priority_rank(zones)


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class ZoneOrder(ZoneTerm):
    """Place in the queue as it stands (inside by entry time, then by distance); -1 as above."""

    name = "zone_order"
    column = "place"

    def value(self, zones, x, y, radius, rect):  # noqa: ANN001, ANN201
        return zn.current_rank(zones, x, y, rect)


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class InZone(ZoneTerm):
    """1 while the robot's disc overlaps the zone."""

    name = "in_zone"
    column = "inside"

    def value(self, zones, x, y, radius, rect):  # noqa: ANN001, ANN201
        return zones.phase == zn.INSIDE


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class EnteringZone(ZoneTerm):
    """1 while the robot straddles the zone's edge on its way in."""

    name = "entering_zone"
    column = "entering"

    def value(self, zones, x, y, radius, rect):  # noqa: ANN001, ANN201
        return zn.straddling(zones, x, y, radius, rect)[0]


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class ExitingZone(ZoneTerm):
    """1 while the robot straddles the zone's edge on its way out."""

    name = "exiting_zone"
    column = "exiting"

    def value(self, zones, x, y, radius, rect):  # noqa: ANN001, ANN201
        return zn.straddling(zones, x, y, radius, rect)[1]


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class ZoneEnteringCount(ZoneTerm):
    """Number of robots straddling the zone's edge on their way in (the same for every robot)."""

    name = "zone_entering_count"
    column = "entering_count"

    def value(self, zones, x, y, radius, rect):  # noqa: ANN001, ANN201
        entering = zn.straddling(zones, x, y, radius, rect)[0]
        return jnp.broadcast_to(jnp.sum(entering, axis=0), entering.shape)


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class ZoneExitingCount(ZoneTerm):
    """Number of robots straddling the zone's edge on their way out."""

    name = "zone_exiting_count"
    column = "exiting_count"

    def value(self, zones, x, y, radius, rect):  # noqa: ANN001, ANN201
        exiting = zn.straddling(zones, x, y, radius, rect)[1]
        return jnp.broadcast_to(jnp.sum(exiting, axis=0), exiting.shape)
