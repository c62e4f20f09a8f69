"""Conflict zones: who takes part, who is in, who goes next (SocialGym 2.0's zone bookkeeping).

A zone is an axis-aligned rectangle from the map (``params.map.zone_rect [Z, 4]``). Everything
here is ``[R, Z]``: one entry per robot and zone.

* **Participants**: robots whose route (straight segments between its waypoints) passes through
  the zone, decided at reset. Only they are ranked; the others read -1.
* **Phase**: 0 = not yet entered, 1 = inside, 2 = left. A robot is *in* the zone while its disc
  overlaps the rectangle; it *enters* on the step its phase goes 0 -> 1 and *exits* on 1 -> 2.
* **Entering / exiting** (straddling an edge): in the zone but not wholly inside it, before /
  after the first step its whole disc was inside. (SocialGym tested the rectangle's left and right
  edges; this also works for zones crossed bottom to top.)
* **Priority**: a random order drawn at reset (the paper's Enforced Order: "a random but specific
  order"). Read as a rank among participants that have not left yet, so the next robot due is 0.
* **Current order**: the rank of the robot in the queue as it stands: robots inside first, by
  entry time, then the ones outside by distance to the zone (ties by robot index).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct
from jax import Array

BEFORE, INSIDE, LEFT = 0, 1, 2
_QUEUE_OFFSET = 1.0e6  # robots inside sort ahead of every distance (their key: entry step - this)


@struct.dataclass
class ZoneState:
    """Per robot and zone, ``[R, Z]``."""

    participant: Array  # bool: the robot's route passes through the zone
    priority_key: Array  # float in [0, 1): smaller goes first
    phase: Array  # int32: BEFORE, INSIDE or LEFT
    was_contained: Array  # bool: the whole disc has been inside the zone
    entered_at: Array  # int32: step of entry (0 before)


def no_zones(num_robots: int) -> ZoneState:
    """Books of ``num_robots`` robots and no zone (``[R, 0]``), with the leaf dtypes that
    :func:`start_zones` gives: what a world without tracked zones carries."""
    empty = (num_robots, 0)
    return ZoneState(participant=jnp.zeros(empty, bool),
                     priority_key=jnp.zeros(empty, jnp.float32),
                     phase=jnp.zeros(empty, jnp.int32),
                     was_contained=jnp.zeros(empty, bool),
                     entered_at=jnp.zeros(empty, jnp.int32))


def route_crosses_rects(route_x: Array, route_y: Array, rect: Array, margin: Array) -> Array:
    """Whether each polyline ``[R, L]`` passes within ``margin [R]`` (m) of each rectangle
    ``[Z, 4]`` (slab test on every segment, rectangles grown by the margin). Returns ``[R, Z]``."""
    ax, ay = route_x[:, :-1, None], route_y[:, :-1, None]  # [R, L-1, 1]
    dx, dy = route_x[:, 1:, None] - ax, route_y[:, 1:, None] - ay
    m = margin[:, None, None]
    lo_x, lo_y = rect[None, None, :, 0] - m, rect[None, None, :, 1] - m
    hi_x, hi_y = rect[None, None, :, 2] + m, rect[None, None, :, 3] + m

    def slab(a: Array, d: Array, lo: Array, hi: Array) -> tuple[Array, Array]:
        moving = jnp.abs(d) > 1e-9
        inv = 1.0 / jnp.where(moving, d, 1.0)
        t1, t2 = (lo - a) * inv, (hi - a) * inv
        inside = (a >= lo) & (a <= hi)
        enter = jnp.where(moving, jnp.minimum(t1, t2), jnp.where(inside, -jnp.inf, jnp.inf))
        leave = jnp.where(moving, jnp.maximum(t1, t2), jnp.where(inside, jnp.inf, -jnp.inf))
        return enter, leave

    ex, lx = slab(ax, dx, lo_x, hi_x)
    ey, ly = slab(ay, dy, lo_y, hi_y)
    t_in = jnp.maximum(jnp.maximum(ex, ey), 0.0)
    t_out = jnp.minimum(jnp.minimum(lx, ly), 1.0)
    return jnp.any(t_in <= t_out, axis=1)


def disc_rect_distance(x: Array, y: Array, rect: Array) -> Array:
    """Distance (m) from points ``[R]`` to rectangles ``[Z, 4]`` (0 inside); ``[R, Z]``."""
    gap_x = jnp.maximum(jnp.maximum(rect[None, :, 0] - x[:, None], x[:, None] - rect[None, :, 2]),
                        0.0)
    gap_y = jnp.maximum(jnp.maximum(rect[None, :, 1] - y[:, None], y[:, None] - rect[None, :, 3]),
                        0.0)
    return jnp.sqrt(gap_x * gap_x + gap_y * gap_y)


def overlaps(x: Array, y: Array, radius: Array, rect: Array) -> Array:
    """Whether each disc ``[R]`` overlaps each rectangle ``[Z, 4]``; ``[R, Z]``."""
    return disc_rect_distance(x, y, rect) < radius[:, None]


def contained(x: Array, y: Array, radius: Array, rect: Array) -> Array:
    """Whether each disc ``[R]`` lies wholly inside each rectangle ``[Z, 4]``; ``[R, Z]``."""
    r = radius[:, None]
    return ((x[:, None] - r >= rect[None, :, 0]) & (x[:, None] + r <= rect[None, :, 2])
            & (y[:, None] - r >= rect[None, :, 1]) & (y[:, None] + r <= rect[None, :, 3]))


def start_zones(
    key: Array, route_x: Array, route_y: Array, x: Array, y: Array, radius: Array,
    present: Array, rect: Array,
) -> ZoneState:
    """Zone state at reset: participants, a random priority, and who already starts inside.
    Without zones (``rect`` ``[0, 4]``: none on the map, or no term reads them) the books are
    :func:`no_zones` and nothing is computed."""
    num_robots, num_zones = x.shape[0], rect.shape[0]
    if num_zones == 0:
        return no_zones(num_robots)
    participant = route_crosses_rects(route_x, route_y, rect, radius) & present[:, None]
    inside = overlaps(x, y, radius, rect) & participant
    return ZoneState(
        participant=participant,
        priority_key=jax.random.uniform(key, (num_robots, num_zones)),
        phase=jnp.where(inside, INSIDE, BEFORE).astype(jnp.int32),
        was_contained=contained(x, y, radius, rect) & participant,
        entered_at=jnp.zeros((num_robots, num_zones), jnp.int32),
    )


def update_zones(
    zones: ZoneState, x: Array, y: Array, radius: Array, rect: Array, time: Array
) -> ZoneState:
    """Advance phases after a step; ``time`` is the step just completed. Books without zones
    (``[R, 0]``) are returned as they are."""
    if rect.shape[0] == 0:
        return zones
    now_in = overlaps(x, y, radius, rect) & zones.participant
    entered = (zones.phase == BEFORE) & now_in
    exited = (zones.phase == INSIDE) & ~now_in
    phase = jnp.where(entered, INSIDE, jnp.where(exited, LEFT, zones.phase))
    return zones.replace(
        phase=phase.astype(jnp.int32),
        was_contained=zones.was_contained | (contained(x, y, radius, rect) & zones.participant),
        entered_at=jnp.where(entered, time, zones.entered_at),
    )


def _rank(key: Array, eligible: Array) -> Array:
    """Rank ``[R, Z]`` of each eligible robot by ``key`` among the eligible ones of its zone
    (ties by robot index); -1 where not eligible."""
    num_robots = key.shape[0]
    index = jnp.arange(num_robots)
    ahead = (key[None, :, :] < key[:, None, :]) | (
        (key[None, :, :] == key[:, None, :]) & (index[None, :, None] < index[:, None, None]))
    count = jnp.sum(ahead & eligible[None, :, :], axis=1)  # [R, Z]
    return jnp.where(eligible, count, -1)


def waiting(zones: ZoneState) -> Array:
    """``[R, Z]`` participants that have not left the zone yet."""
    return zones.participant & (zones.phase != LEFT)


def priority_rank(zones: ZoneState) -> Array:
    """``[R, Z]`` int: the assigned turn among robots that have not left (0 = due now), -1 for
    robots that left or do not take part."""
    return _rank(zones.priority_key, waiting(zones))


def current_rank(zones: ZoneState, x: Array, y: Array, rect: Array) -> Array:
    """``[R, Z]`` int: place in the queue as it stands (inside first by entry time, then outside
    by distance to the zone), -1 for robots that left or do not take part."""
    queue_key = jnp.where(zones.phase == INSIDE,
                          zones.entered_at.astype(jnp.float32) - _QUEUE_OFFSET,
                          disc_rect_distance(x, y, rect))
    return _rank(queue_key, waiting(zones))


def straddling(zones: ZoneState, x: Array, y: Array, radius: Array, rect: Array
               ) -> tuple[Array, Array]:
    """``(entering, exiting) [R, Z]`` bool: on the zone's edge, before / after having been
    wholly inside."""
    edge = (zones.phase == INSIDE) & ~contained(x, y, radius, rect)
    return edge & ~zones.was_contained, edge & zones.was_contained
