"""Which walls each pedestrian meets: every wall of the map (the laws as published), or, with a
range, the walls closer than it, read from the map's wall grid where the map holds many walls.

The wall grid (:func:`sgjax.maps.arrays.compile_map`) lists, for each cell, every wall within
the map's ``reach`` of any point of the cell; ``sgjax.make`` grows the reach to the
pedestrians' range (``human_range``) when they have one. So a pedestrian's cell list holds
every wall within the range, and the forces through the lists equal those over every wall
with the same range (the contacts' broad phase, :func:`sgjax.kernels.contacts.uses_broad_phase`,
decides where the lists pay: SocialGym 2.0's building floors, not the mini-games)."""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array

from sgjax.kernels.contacts import uses_broad_phase
from sgjax.kernels.geometry import point_segment_offset
from sgjax.kernels.orca import nearest_places
from sgjax.maps.arrays import MapArrays


def uses_wall_lists(m: MapArrays, wall_range: float | None) -> bool:
    """Whether pedestrians within ``wall_range`` m read their walls from ``m``'s cell lists
    (static): with a range the lists cover (the map's ``reach`` at least the range) on a map
    whose contacts take the broad phase."""
    return (wall_range is not None and uses_broad_phase(m)
            and float(getattr(m, "reach", 0.0)) >= wall_range)


def wall_offsets(x: Array, y: Array, m: MapArrays, wall_range: float | None
                 ) -> tuple[Array, Array, Array, Array]:
    """``(ox, oy, valid, index)`` ``[H, K]``: the vector from each wall's nearest point to each
    pedestrian at ``x, y`` ``[H]`` (m), whether the wall acts (a real wall, and with
    ``wall_range`` closer than it) and its row in the map's walls. ``K`` is every wall (``W``)
    without the lists, a cell list's length (``Kw``) with them (:func:`uses_wall_lists`)."""
    if uses_wall_lists(m, wall_range):
        index = m.cell_walls[m.cell_of(x, y)]  # [H, Kw]
        walls = (m.wall_x1[index], m.wall_y1[index], m.wall_x2[index], m.wall_y2[index])
        valid = m.wall_valid[index]
    else:
        count = m.wall_x1.shape[0]
        index = jnp.broadcast_to(jnp.arange(count, dtype=jnp.int32), (x.shape[0], count))
        walls = (m.wall_x1, m.wall_y1, m.wall_x2, m.wall_y2)
        valid = jnp.broadcast_to(m.wall_valid, index.shape)
    ox, oy = point_segment_offset(x[:, None], y[:, None], *walls)
    if wall_range is not None:
        valid = valid & (ox * ox + oy * oy < wall_range * wall_range)
    return ox, oy, valid, index


def nearest_walls_in_range(x: Array, y: Array, m: MapArrays, k: int,
                           wall_range: float | None) -> tuple[Array, Array]:
    """The rows of the ``k`` (static) nearest acting walls of pedestrians at ``x, y`` ``[H]``
    (:func:`wall_offsets`): ``(index [H, k'], valid [H, k'])``, ``k' = min(k, K)``."""
    ox, oy, valid, index = wall_offsets(x, y, m, wall_range)
    near, acting = nearest_places(ox, oy, valid, k)
    return jnp.take_along_axis(index, near, axis=1), acting
