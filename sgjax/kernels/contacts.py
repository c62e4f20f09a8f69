"""Contacts for disc robots: robot-robot overlap resolution and swept robot-wall checks."""

from __future__ import annotations

from typing import Protocol

import jax.numpy as jnp
from jax import Array

from sgjax.kernels.geometry import safe_norm, swept_disc_segment_toi

WALL_SKIN = 1e-3  # m: robots stop this far short of the contact point with a wall
# m: robots whose gap is at most this are in contact. Two robots pushed apart rest at a gap of
# about +-1e-6 m (float32 rounding of positions of a few metres), so a test at exactly zero
# called a resting pair touching or apart by the last bit, which differs between CPUs, and
# counted a new collision onset at every flip. The time-to-collision metrics use it too.
CONTACT_GAP = 1e-5


def separate_robots(
    x: Array, y: Array, radius: Array, in_world: Array, movable: Array | None = None,
) -> tuple[Array, Array, Array]:
    """Push overlapping robots apart along their centre line: each by half the overlap, or a
    movable robot by all of it when the other is not movable (a parked robot).

    ``x, y, radius, in_world, movable`` are ``[R]``; robots not ``in_world`` neither push nor get
    pushed; robots not ``movable`` (default: all movable) push but are never pushed. Returns the
    push ``(px, py)`` ``[R]`` (m) and a per-robot contact flag ``[R]`` (overlapping, or apart by at
    most ``CONTACT_GAP``).
    """
    num_robots = x.shape[0]
    dx = x[:, None] - x[None, :]
    dy = y[:, None] - y[None, :]
    dist = safe_norm(dx, dy)
    pair = in_world[:, None] & in_world[None, :] & ~jnp.eye(num_robots, dtype=bool)
    overlap = jnp.where(pair, radius[:, None] + radius[None, :] - dist, 0.0)
    touching = pair & (overlap >= -CONTACT_GAP)
    # Coincident centres: separate along x, lower index to the left.
    index = jnp.arange(num_robots)
    fallback = jnp.where(index[:, None] < index[None, :], -1.0, 1.0)
    close = dist < 1e-6
    ux = jnp.where(close, fallback, dx / jnp.where(close, 1.0, dist))
    uy = jnp.where(close, 0.0, dy / jnp.where(close, 1.0, dist))
    movable = in_world if movable is None else movable
    share = jnp.where(movable[:, None], jnp.where(movable[None, :], 0.5, 1.0), 0.0)
    push = jnp.where(overlap > 0.0, share * overlap, 0.0)
    return jnp.sum(push * ux, axis=1), jnp.sum(push * uy, axis=1), jnp.any(touching, axis=1)


class Walls(Protocol):
    """The wall arrays a contact test reads (``sgjax.maps.MapArrays`` has them): segment ends
    ``wall_x1, wall_y1, wall_x2, wall_y2`` ``[W]`` (m) and ``wall_valid`` ``[W]`` bool (padding
    slots are False); the wall grid ``cell_walls [C, Kw]`` (``cell_of`` maps points to cells)
    whose lists hold every wall within ``reach`` m of any point of the cell (``reach`` 0: no
    such promise)."""

    wall_x1: Array
    wall_y1: Array
    wall_x2: Array
    wall_y2: Array
    wall_valid: Array
    cell_walls: Array
    reach: float

    def cell_of(self, x: Array, y: Array) -> Array: ...


# Walls per listed wall from which the broad phase pays: gathering a cell's list costs about
# what testing several walls by broadcast does (bench/building_scale.py, 2-core CPU, 4 robots
# x 64 environments: the office's 44 walls against lists of 8 step 4% slower through the
# lists; GDC1's 1,374 against 62 1.9x faster, GDC3's 5,647 against 134 3.4x faster).
BROAD_PHASE_RATIO = 8


def uses_broad_phase(m: Walls) -> bool:
    """Whether contact tests on ``m`` go through its wall grid (static: shapes and ``reach``):
    when the grid promises a reach and a cell's list is at most 1/:data:`BROAD_PHASE_RATIO`
    of the walls (the shipped maps test every wall; SocialGym 2.0's building floors take the
    lists)."""
    reach = getattr(m, "reach", 0.0)  # wall arrays without a grid: every wall is tested
    return reach > 0.0 and m.cell_walls.shape[-1] * BROAD_PHASE_RATIO <= m.wall_x1.shape[-1]


def clamp_to_walls(
    x: Array, y: Array, dx: Array, dy: Array, radius: Array, m: Walls
) -> tuple[Array, Array, Array]:
    """Cut each displacement ``(dx, dy)`` ``[B]`` (m) of discs at ``(x, y)`` ``[B]`` of
    ``radius`` ``[B]`` or scalar (m) at the first wall contact (swept disc test).

    Returns the allowed displacement and a per-body wall-contact flag. The body stops
    ``WALL_SKIN`` short of the contact, so no step size or speed puts it inside a wall.

    On a map with a large wall count (:func:`uses_broad_phase`) only the walls in the list of
    the body's grid cell are tested: the swept disc reaches no farther than ``|d| + radius``
    from the body, so the result is the all-walls result whenever that is within the grid's
    ``reach`` (2.5 m and more; a step moves a body centimetres). A displacement reaching
    beyond it (none that the dynamics make) is cut where it would leave the reach, counted
    as a contact: never a wall passed unseen. Elsewhere every wall is tested (broadcast
    against constants: faster on the CPU than gathering short lists).
    """
    radius = jnp.broadcast_to(radius, x.shape)
    length = safe_norm(dx, dy)
    if uses_broad_phase(m):
        near = m.cell_walls[m.cell_of(x, y)]  # [B, Kw]
        walls = (m.wall_x1[near], m.wall_y1[near], m.wall_x2[near], m.wall_y2[near])
        valid = m.wall_valid[near]
    else:
        walls = (m.wall_x1, m.wall_y1, m.wall_x2, m.wall_y2)
        valid = m.wall_valid
    toi = swept_disc_segment_toi(x[:, None], y[:, None], dx[:, None], dy[:, None],
                                 radius[:, None], *walls)
    toi = jnp.min(jnp.where(valid, toi, jnp.inf), axis=1)
    if uses_broad_phase(m):  # a step reaching past the lists stops where it would leave them
        horizon = (m.reach - radius) / jnp.maximum(length, 1e-9)
        toi = jnp.where(horizon < 1.0, jnp.minimum(toi, jnp.maximum(horizon, 0.0)), toi)
    hit = toi <= 1.0
    fraction = jnp.where(hit, jnp.maximum(toi - WALL_SKIN / jnp.maximum(length, 1e-9), 0.0), 1.0)
    return dx * fraction, dy * fraction, hit
