"""Planar geometry on separate x / y arrays (metres).

Everything here broadcasts: pass robot coordinates shaped ``[R, 1]`` and wall coordinates shaped
``[W]`` to get ``[R, W]`` results. Components are kept as separate arrays because XLA's CPU backend
vectorises the innermost axis, and a trailing axis of size 2 wastes it (see DESIGN.md).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

_TINY = 1e-12


def wrap_angle(angle: Array) -> Array:
    """Wrap angles (rad) to (-pi, pi]."""
    wrapped = jnp.mod(angle + jnp.pi, 2.0 * jnp.pi) - jnp.pi
    return jnp.where(wrapped == -jnp.pi, jnp.pi, wrapped)


def safe_norm(x: Array, y: Array) -> Array:
    """Euclidean norm with a finite gradient at the origin (below 1e-6 m it returns
    ``|v|^2 / 1e-6``, which is smaller still). Written as ``sq * rsqrt(sq)``: XLA's CPU backend
    vectorises it, where a ``where``-guarded ``sqrt`` runs several times slower."""
    sq = x * x + y * y
    return sq * jax.lax.rsqrt(jnp.maximum(sq, _TINY))


def point_segment_offset(
    px: Array, py: Array, ax: Array, ay: Array, bx: Array, by: Array
) -> tuple[Array, Array]:
    """Vector (m) from the nearest point of segments ``a-b`` to points ``p``; broadcasts over
    all arguments. The segments' inverse squared lengths are computed at the segments' shape."""
    ex, ey = bx - ax, by - ay
    inv_length_sq = 1.0 / jnp.maximum(ex * ex + ey * ey, _TINY)
    qx, qy = px - ax, py - ay
    t = jnp.clip((qx * ex + qy * ey) * inv_length_sq, 0.0, 1.0)
    return qx - t * ex, qy - t * ey


def point_segment_distance_sq(
    px: Array, py: Array, ax: Array, ay: Array, bx: Array, by: Array
) -> Array:
    """Squared distance (m^2) from points ``p`` to segments ``a-b`` (broadcasts)."""
    ox, oy = point_segment_offset(px, py, ax, ay, bx, by)
    return ox * ox + oy * oy


def point_segment_distance(
    px: Array, py: Array, ax: Array, ay: Array, bx: Array, by: Array
) -> Array:
    """Distance (m) from points ``p`` to segments ``a-b`` (finite gradient at zero)."""
    sq = point_segment_distance_sq(px, py, ax, ay, bx, by)
    safe_sq = jnp.where(sq > _TINY, sq, 1.0)
    return jnp.where(sq > _TINY, jnp.sqrt(safe_sq), 0.0)


def _first_circle_hit(
    mx: Array, my: Array, dx: Array, dy: Array, radius: Array
) -> Array:
    """Fraction t in [0, 1] at which ``m + t d`` first reaches distance ``radius`` from the origin.

    Returns 0 when the motion starts inside the circle and heads further in, and ``inf`` when the
    circle is not reached within the step.
    """
    a = dx * dx + dy * dy
    b = mx * dx + my * dy
    c = mx * mx + my * my - radius * radius
    disc = b * b - a * c
    ok = (b < 0.0) & (disc >= 0.0) & (a > _TINY)
    safe_disc = jnp.where(ok, disc, 0.0)
    root = (-b - jnp.sqrt(jnp.where(ok, safe_disc, 1.0))) / jnp.where(ok, a, 1.0)
    t = jnp.where(c <= 0.0, 0.0, root)
    return jnp.where(ok & (t <= 1.0), jnp.maximum(t, 0.0), jnp.inf)


def swept_disc_segment_toi(
    px: Array,
    py: Array,
    dx: Array,
    dy: Array,
    radius: Array,
    ax: Array,
    ay: Array,
    bx: Array,
    by: Array,
) -> Array:
    """Time of impact of a disc moving from ``p`` by ``d`` against segments ``a-b``.

    The disc (radius ``radius``) touches a segment when its centre reaches the segment's capsule
    (the segment inflated by ``radius``). Returns the fraction of the motion in ``[0, 1]`` at the
    first touch, or ``inf`` when the disc does not touch the segment during this motion. A disc that
    starts inside a capsule gets 0 if it moves further in, and ``inf`` if it moves out, so a body
    can always back away from a wall it touches. Broadcasts over all arguments.
    """
    ex, ey = bx - ax, by - ay
    length = safe_norm(ex, ey)
    inv_len = 1.0 / jnp.maximum(length, _TINY)
    ux, uy = ex * inv_len, ey * inv_len
    nx, ny = -uy, ux
    # Straight sides of the capsule.
    s0 = (px - ax) * nx + (py - ay) * ny
    sd = dx * nx + dy * ny
    side = jnp.where(s0 >= 0.0, 1.0, -1.0)
    approach = -side * sd  # > 0 when moving toward the segment's line
    gap = jnp.abs(s0) - radius
    safe_approach = jnp.where(approach > _TINY, approach, 1.0)
    t_side = jnp.where(gap <= 0.0, 0.0, gap / safe_approach)
    along = (px + t_side * dx - ax) * ux + (py + t_side * dy - ay) * uy
    side_hit = (approach > _TINY) & (t_side <= 1.0) & (along >= 0.0) & (along <= length)
    t_side = jnp.where(side_hit, t_side, jnp.inf)
    # Rounded ends of the capsule.
    t_a = _first_circle_hit(px - ax, py - ay, dx, dy, radius)
    t_b = _first_circle_hit(px - bx, py - by, dx, dy, radius)
    return jnp.minimum(t_side, jnp.minimum(t_a, t_b))


def segments_intersect(
    p1: tuple[float, float],
    p2: tuple[float, float],
    q1: tuple[float, float],
    q2: tuple[float, float],
) -> bool:
    """Whether closed segments p1-p2 and q1-q2 intersect (host-side helper for map validation;
    :func:`segments_intersect_pairs` for many pairs at once)."""
    return bool(segments_intersect_pairs(np.array([[*p1, *p2]], np.float64),
                                         np.array([[*q1, *q2]], np.float64))[0])


def segments_intersect_pairs(p: np.ndarray, q: np.ndarray, xp: Any = np) -> np.ndarray:
    """Whether closed segments ``p [..., 4]`` and ``q [..., 4]`` (x1, y1, x2, y2) intersect,
    pair by pair with broadcasting: ``[...]`` bool. Touching counts. ``xp``: ``numpy``
    (host-side map validation, float64) or ``jax.numpy`` (inside ``jit``: generated worlds)."""
    p1, p2, q1, q2 = p[..., :2], p[..., 2:], q[..., :2], q[..., 2:]

    def orient(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
        return ((b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1])
                - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0]))

    def on_segment(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
        low, high = xp.minimum(a, b) - 1e-9, xp.maximum(a, b) + 1e-9
        return xp.all((low <= c) & (c <= high), axis=-1)

    d1, d2 = orient(q1, q2, p1), orient(q1, q2, p2)
    d3, d4 = orient(p1, p2, q1), orient(p1, p2, q2)
    proper = (((d1 > 0) != (d2 > 0)) & ((d3 > 0) != (d4 > 0)) & (d1 * d2 != 0)
              & (d3 * d4 != 0))
    eps = 1e-12
    return proper | ((xp.abs(d1) < eps) & on_segment(q1, q2, p1)) | (
        (xp.abs(d2) < eps) & on_segment(q1, q2, p2)) | (
        (xp.abs(d3) < eps) & on_segment(p1, p2, q1)) | (
        (xp.abs(d4) < eps) & on_segment(p1, p2, q2))


# atan(a) / a as a polynomial in a^2 on [0, 1] (least-squares fit on Chebyshev nodes; the
# largest error of atan over [0, 1] is 9e-8 rad, below float32 resolution near pi).
_ATAN_COEFFS = (-0.00483113, 0.02475667, -0.06021899, 0.09967916, -0.14040137, 0.19973681,
                -0.33332303, 0.99999996)


def polynomial_atan2(y: Array, x: Array) -> Array:
    """``atan2(y, x)`` (rad) to within 1e-7 rad, from arithmetic only.

    XLA's CPU backend evaluates ``jnp.arctan2`` one element at a time (about 15 ns each), and a
    select (``jnp.where``, ``copysign``) feeding a reduction also stops it vectorising; this
    uses neither (branches are blended with 0/1 factors). ``(0, 0)`` gives 0.
    """
    ax, ay = jnp.abs(x), jnp.abs(y)
    big, small = jnp.maximum(ax, ay), jnp.minimum(ax, ay)
    a = small / jnp.maximum(big, 1e-30)
    s = a * a
    poly = jnp.full_like(s, _ATAN_COEFFS[0])
    for c in _ATAN_COEFFS[1:]:
        poly = poly * s + c
    r = poly * a
    r = r + (ay > ax).astype(r.dtype) * (0.5 * jnp.pi - 2.0 * r)
    r = r + (x < 0.0).astype(r.dtype) * (jnp.pi - 2.0 * r)
    return r * (1.0 - 2.0 * (y < 0.0).astype(r.dtype))
