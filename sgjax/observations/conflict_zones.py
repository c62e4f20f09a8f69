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
from sgjax.validation import check_positive

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


@OBSERVATIONS.register
@dataclasses.dataclass(frozen=True)
class ZoneAhead(ObservationTerm):
    """The conflict zone ahead, whatever the map's number of zones (so a policy carries between
    worlds): the zone the robot is in, else the nearest zone on its route it has not left.
    Columns: ``ahead`` (1 when there is one), ``distance`` (m from the robot's centre to the
    zone's rectangle, 0 inside), ``priority`` (its assigned turn, 0 = due now), ``place`` (its
    place in the queue as it stands), ``inside``, ``entering`` (on the edge on its way in) and
    ``entering_count`` (robots on that zone's edge on their way in); without a zone ahead
    ``distance`` reads ``horizon`` and the ranks -1."""

    name = "zone_ahead"
    uses_zones = True
    horizon: float = 10.0  # m: the distance read without a zone ahead (and the farthest read)

    def __post_init__(self) -> None:
        check_positive("horizon", self.horizon)

    def columns(self, layout: Layout) -> Columns:
        return Columns.plain("ahead", "distance", "priority", "place", "inside", "entering",
                             "entering_count")

    def __call__(self, inputs: TermInput) -> Array:
        state, params = inputs.state, inputs.params
        r, zones, rect = state.robots, state.zones, params.map.zone_rect
        num_robots = r.x.shape[0]
        if zones.phase.shape[1] == 0:
            none = jnp.zeros(num_robots, jnp.float32)
            return jnp.stack([none, none + self.horizon, none - 1, none - 1, none, none, none],
                             axis=-1)
        distance = zn.disc_rect_distance(r.x, r.y, rect)  # [R, Z]
        inside = zones.phase == zn.INSIDE
        open_ = zn.waiting(zones)
        key = jnp.where(inside, -1.0, jnp.where(open_, distance, jnp.inf))
        pick = jnp.argmin(key, axis=1)  # [R]
        ahead = jnp.isfinite(jnp.min(key, axis=1))

        def at(x: Array) -> Array:
            return jnp.take_along_axis(x, pick[:, None], axis=1)[:, 0]

        entering = zn.straddling(zones, r.x, r.y, params.robots.radius, rect)[0]
        count = jnp.sum(entering, axis=0)[pick]
        columns = [
            ahead, jnp.where(ahead, jnp.minimum(at(distance), self.horizon), self.horizon),
            jnp.where(ahead, at(zn.priority_rank(zones)), -1),
            jnp.where(ahead, at(zn.current_rank(zones, r.x, r.y, rect)), -1),
            ahead & at(inside), ahead & at(entering), jnp.where(ahead, count, 0),
        ]
        return jnp.stack([c.astype(jnp.float32) for c in columns], axis=-1)
