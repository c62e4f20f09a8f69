"""Pedestrian groups (``make(..., human_groups=[3, 2])``): members spawn side by side, share
their leader's goal and walking speed, and, under the social-force models, feel the group
forces of Moussaid, Perozo, Garnier, Helbing and Theraulaz 2010 ("The walking behaviour of
pedestrian social groups", PLoS ONE), in PySocialForce's form:

* coherence: ``c (p_g - p_i) (tanh(|p_g - p_i| - (n - 1) / 2) + 1) / 2`` toward the group's
  centre of mass ``p_g`` (all ``n`` members), strongest once a member is farther than
  ``(n - 1) / 2`` m from it;
* repulsion: ``r sum_j (p_i - p_j)`` over the members closer than ``threshold``;
* gaze: with ``phi`` the angle between the walking direction (to the target) and the direction
  to the other members' centre, ``-g (phi - fov) v`` once ``phi > fov``: a member who would
  have to turn its head past ``fov`` to see the others slows down. This is the paper's form,
  proportional to the velocity ``v``; PySocialForce's ``GroupGazeForce`` uses the unit walking
  direction instead, which holds a member back even at rest, and a group of three then stood
  before a 1 m door for good (measured); its simulator's default, ``GroupGazeForceAlt``, has no
  field of view at all.

Constants (:class:`GroupParams`; PySocialForce's README and ``config/default.toml``):
coherence 3.0, repulsion 1.0 within 0.55 m, gaze 4.0 beyond 90 degrees; m/s^2 per m (or per
rad). ``leader`` ``[H]`` int32 is each pedestrian's group leader (itself when alone), a param:
group sizes change without recompiling. ORCA pedestrians spawn and walk as groups but feel no
group force (ORCA has none); HSFM adds them, times the mass, to its interaction force.
"""

from __future__ import annotations

from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from jax import Array

from sgjax.kernels.geometry import safe_norm


@struct.dataclass
class GroupParams:
    """Group membership and the group-force constants (batch them for a sweep)."""

    leader: Array  # [H] int32: each pedestrian's group leader (itself when alone)
    coherence: Array | float = 3.0
    repulsion: Array | float = 1.0
    threshold: Array | float = 0.55  # m: repulsion range between members
    gaze: Array | float = 4.0
    fov: Array | float = float(np.pi / 2)  # rad: half the field of view


def leaders(sizes: Sequence[int], max_humans: int, where: str = "human_groups") -> np.ndarray:
    """``[H]`` leader indices for groups of ``sizes`` filling the first pedestrian slots in
    order (the rest walk alone). Errors name ``where``."""
    sizes = list(sizes)
    if any(isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1 for n in sizes):
        raise ValueError(f"{where} must be a list of group sizes >= 1, got {sizes}")
    if sum(sizes) > max_humans:
        raise ValueError(f"{where}={sizes} holds {sum(sizes)} pedestrians, more than "
                         f"max_humans={max_humans}")
    out = np.arange(max_humans, dtype=np.int32)
    start = 0
    for n in sizes:
        out[start:start + n] = start
        start += n
    return out


def group_forces(gp: GroupParams, x: Array, y: Array, vx: Array, vy: Array, tx: Array,
                 ty: Array, active: Array) -> tuple[Array, Array]:
    """Group forces per unit mass ``(fx, fy)`` ``[H]`` (m/s^2) on pedestrians at ``x, y``
    moving at ``vx, vy`` (m/s) toward ``tx, ty`` (m); zero for pedestrians alone."""
    num = x.shape[0]
    same = (gp.leader[:, None] == gp.leader[None, :]) & active[None, :] & active[:, None]
    member = same.astype(jnp.float32)  # [H, H], with the diagonal
    count = jnp.sum(member, axis=1)
    in_group = active & (count > 1.5)
    cx = jnp.sum(member * x[None, :], axis=1) / jnp.maximum(count, 1.0)
    cy = jnp.sum(member * y[None, :], axis=1) / jnp.maximum(count, 1.0)
    # Coherence toward the centre of mass of all members.
    ax, ay = cx - x, cy - y
    soft = (jnp.tanh(safe_norm(ax, ay) - (count - 1.0) / 2.0) + 1.0) / 2.0
    fx, fy = gp.coherence * soft * ax, gp.coherence * soft * ay
    # Repulsion between members closer than the threshold.
    dx, dy = x[:, None] - x[None, :], y[:, None] - y[None, :]
    close = member * (1.0 - jnp.eye(num)) * (safe_norm(dx, dy) < gp.threshold)
    fx = fx + gp.repulsion * jnp.sum(close * dx, axis=1)
    fy = fy + gp.repulsion * jnp.sum(close * dy, axis=1)
    # Gaze: the others' centre (without the pedestrian) against the walking direction.
    others = jnp.maximum(count - 1.0, 1.0)
    ox, oy = (cx * count - x) / others - x, (cy * count - y) / others - y
    wx, wy = tx - x, ty - y
    walk = safe_norm(wx, wy)
    ux, uy = wx / jnp.maximum(walk, 1e-9), wy / jnp.maximum(walk, 1e-9)
    cos_phi = (ux * ox + uy * oy) / jnp.maximum(safe_norm(ox, oy), 1e-9)
    phi = jnp.arccos(jnp.clip(cos_phi, -1.0, 1.0))
    turn = jnp.maximum(phi - gp.fov, 0.0)
    fx, fy = fx - gp.gaze * turn * vx, fy - gp.gaze * turn * vy
    return jnp.where(in_group, fx, 0.0), jnp.where(in_group, fy, 0.0)


def spawn_beside_leaders(leader: Array, slot: Array, free: Array, spawn_x: Array,
                         spawn_y: Array) -> Array:
    """Slots ``[H]``: each follower (``leader[i] != i``) moves to the free slot nearest its
    leader's, in index order; leaders and loners keep ``slot``. ``free`` ``[S]``: slots that
    nobody took and no robot blocks."""
    num = leader.shape[0]
    used = jnp.zeros(spawn_x.shape, bool).at[slot].set(leader == jnp.arange(num))

    def place(i: Array, carry: tuple[Array, Array]) -> tuple[Array, Array]:
        out, used = carry
        lx, ly = spawn_x[out[leader[i]]], spawn_y[out[leader[i]]]
        gap = jnp.square(spawn_x - lx) + jnp.square(spawn_y - ly)
        pick = jnp.argmin(jnp.where(free & ~used, gap, jnp.inf))
        chosen = jnp.where(leader[i] != i, pick, out[i])
        return out.at[i].set(chosen), used.at[chosen].set(True)

    out, _ = jax.lax.fori_loop(0, num, place, (slot, used))
    return out
