"""Social-force laws for pedestrians, on separate x / y arrays (m, m/s, m/s^2).

Every function maps pedestrians ``[H]`` (and the bodies they react to, ``[M]``) to a force per
unit mass ``(fx, fy)`` ``[H]``. Constants come from :class:`SocialForceParams`, a pytree, so a
``vmap`` over it is a parameter sweep and ``jax.grad`` through it fits the constants.

Two interaction laws (``../shared/reference/socialnav.md`` section B):

* Moussaid et al. 2009 (the "extended" social force of PySocialForce, pedsim and lightsfm),
  :func:`moussaid_interaction`, with the obstacle term :func:`exponential_wall_force`;
* Helbing and Molnar 1995 (the elliptical potential), :func:`helbing_interaction`, with the
  boundary potential :func:`helbing_wall_force`.

Both share the driving term :func:`desired_force`.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.kernels.geometry import polynomial_atan2, safe_norm

_TINY = 1e-9


@struct.dataclass
class SocialForceParams:
    """Force-law constants (scalars; any of them may be batched for a sweep)."""

    tau: Array | float = 0.5  # s: relaxation time of the driving term
    # Moussaid 2009 interaction (PySocialForce default.toml [social_force], [obstacle_force])
    social_strength: Array | float = 5.1  # m/s^2: A (PySocialForce, pedsim_ros)
    lambda_importance: Array | float = 2.0  # weight of the relative velocity in D
    gamma: Array | float = 0.35  # B = gamma |D| (m)
    n: Array | float = 2.0  # angular decay of the turning term
    n_prime: Array | float = 3.0  # angular decay of the braking term
    obstacle_strength: Array | float = 10.0  # m/s^2
    obstacle_sigma: Array | float = 0.2  # m
    obstacle_threshold: Array | float = 3.0  # m of clearance beyond which a wall is ignored
    # Helbing and Molnar 1995 potentials (PySocialForce potentials.py, fieldofview.py)
    v0: Array | float = 2.1  # m^2/s^2: pedestrian potential strength V0
    sigma: Array | float = 0.3  # m: pedestrian potential range
    ellipse_dt: Array | float = 2.0  # s: how far ahead another's step stretches its ellipse
    u0: Array | float = 10.0  # m^2/s^2: wall potential strength U0
    wall_range: Array | float = 0.2  # m: wall potential range R
    fov_cos: Array | float = math.cos(math.radians(100.0))  # half-angle 100 deg: a 200 deg view
    fov_out_weight: Array | float = 0.5  # weight of others outside the field of view


def unit(x: Array, y: Array) -> tuple[Array, Array, Array]:
    """Unit vector and norm; the zero vector maps to ``(0, 0)`` (vectorisable: no selects)."""
    sq = x * x + y * y
    inv = jax.lax.rsqrt(jnp.maximum(sq, _TINY * _TINY))
    return x * inv, y * inv, sq * inv


SIGN_DEADZONE = 1e-5  # rad: |theta| below this turns neither way (float32 rounding noise)


def _sign(v: Array) -> Array:
    """``sign`` with a dead zone, as arithmetic (a select feeding a reduction stops XLA's CPU
    backend vectorising, so the pair terms below blend with 0/1 factors instead of ``where``).

    Two pedestrians at rest have ``theta = 0`` exactly, but rounding leaves it at +-1e-7, and a
    plain sign would pick the turning direction by that noise (and differ between ``jit`` and
    eager); the dead zone makes it 0, as the exact value is.
    """
    return (v > SIGN_DEADZONE).astype(v.dtype) - (v < -SIGN_DEADZONE).astype(v.dtype)


def _pair_offset(weight: Array) -> Array:
    """1 m for masked pairs (weight 0), 0 otherwise: added to their separation so that a
    pedestrian paired with itself is not at distance 0, whose square root has an infinite
    derivative (``0 x inf`` would turn gradients NaN even though the pair is masked)."""
    return 1.0 - (weight != 0.0).astype(jnp.float32)


def _row(others: Array) -> Array:
    """The others' values as ``[1, M]`` (one row shared by every pedestrian) or ``[H, P]``
    (each pedestrian's own places, :class:`sgjax.humans.neighbors.Pairs`) as given."""
    return others if others.ndim == 2 else others[None, :]


def _flag(condition: Array) -> Array:
    """Boolean as a 0/1 float factor."""
    return condition.astype(jnp.float32)


def desired_force(
    x: Array, y: Array, vx: Array, vy: Array, target_x: Array, target_y: Array,
    speed: Array, tau: Array | float,
) -> tuple[Array, Array]:
    """Relax toward ``speed`` (m/s) along the unit vector to the target: ``(v0 e - v) / tau``."""
    ex, ey, _ = unit(target_x - x, target_y - y)
    return (speed * ex - vx) / tau, (speed * ey - vy) / tau


def moussaid_interaction(
    x: Array, y: Array, vx: Array, vy: Array,
    ox: Array, oy: Array, ovx: Array, ovy: Array,
    weight: Array, p: SocialForceParams, pysocialforce_angle: bool = False,
) -> tuple[Array, Array]:
    """Moussaid et al. 2009 interaction of pedestrians ``[H]`` with bodies ``[M]``.

    ``weight [H, M]`` scales each pair (0 masks it: the pedestrian itself, absent bodies).
    The bodies ``ox, oy, ovx, ovy`` are ``[M]`` (every pedestrian meets all of them) or
    ``[H, M]`` (each its own, :class:`sgjax.humans.neighbors.Pairs`).
    With ``e`` the unit vector from the pedestrian to the other, ``D = lambda (v - v_other) + e``,
    ``t = D / |D|``, ``B = gamma |D|``, ``theta`` the signed angle from ``e`` to ``t`` in
    (-pi, pi] and ``d`` the centre distance::

        f = A exp(-d / B) [-exp(-(n' B theta)^2) t + sign(theta) exp(-(n B theta)^2) left(t)]

    The first term brakes, the second turns away from the other's side.

    ``pysocialforce_angle=True`` reproduces PySocialForce 1.1.2, whose ``theta`` is the raw
    difference ``angle(-t) - angle(-e)`` of two ``arctan2`` values, not wrapped: where it lands
    outside [-pi, pi] (a pair straddling the +x direction) its interaction nearly vanishes.
    Only for the correspondence test; the default is the wrapped angle of the paper.
    """
    rx = _row(ox) - x[:, None] + _pair_offset(weight)
    ry = _row(oy) - y[:, None]
    # Written lean on purpose: XLA's CPU backend stops vectorising a fused pair kernel once it
    # holds too many distinct terms, so t = D / |D| is folded into the two scalar factors and
    # no select or arctan2 appears (bench/throughput.py --table pedestrians shows the cost).
    dist = jnp.sqrt(rx * rx + ry * ry)
    inv_dist = 1.0 / jnp.maximum(dist, _TINY)
    dx = p.lambda_importance * (vx[:, None] - _row(ovx)) + rx * inv_dist
    dy = p.lambda_importance * (vy[:, None] - _row(ovy)) + ry * inv_dist
    d_norm = jnp.sqrt(dx * dx + dy * dy)
    # theta from e x D and e . D (|D| > 0 and |r| drop out of the angle).
    theta = polynomial_atan2(rx * dy - ry * dx, rx * dx + ry * dy)
    if pysocialforce_angle:
        theta = polynomial_atan2(-dy, -dx) - polynomial_atan2(-ry, -rx)
    b = jnp.maximum(p.gamma * d_norm, _TINY)
    scale = p.social_strength * weight / jnp.maximum(d_norm, _TINY)
    brake = scale * jnp.exp(-dist / b - jnp.square(p.n_prime * b * theta))
    turn = scale * _sign(theta) * jnp.exp(-dist / b - jnp.square(p.n * b * theta))
    fx = -brake * dx - turn * dy
    fy = -brake * dy + turn * dx
    return jnp.sum(fx, axis=1), jnp.sum(fy, axis=1)


def helbing_interaction(
    x: Array, y: Array, heading_x: Array, heading_y: Array,
    ox: Array, oy: Array, ovx: Array, ovy: Array,
    weight: Array, p: SocialForceParams,
) -> tuple[Array, Array]:
    """Helbing and Molnar 1995 repulsion ``-grad V(b)`` with ``V = V0 exp(-b / sigma)``.

    ``b`` is the semi-minor axis of the ellipse through the pedestrian with foci at the other
    body and at its position one ``ellipse_dt`` step ahead: with ``r`` from the other to the
    pedestrian and ``s = v_other ellipse_dt``, ``2b = sqrt((|r| + |r - s|)^2 - |s|^2)``.
    Others outside the field of view (``heading [H]``, a unit vector: the desired direction)
    count ``fov_out_weight``. ``weight [H, M]`` masks pairs; the bodies are ``[M]`` or
    ``[H, M]`` as in :func:`moussaid_interaction`.
    """
    rx = x[:, None] - _row(ox) + _pair_offset(weight)
    ry = y[:, None] - _row(oy)
    sx = _row(ovx) * p.ellipse_dt
    sy = _row(ovy) * p.ellipse_dt
    ux, uy, r_norm = unit(rx, ry)
    wx, wy, w_norm = unit(rx - sx, ry - sy)
    total = r_norm + w_norm
    b = 0.5 * jnp.sqrt(jnp.maximum(jnp.square(total) - (sx * sx + sy * sy), _TINY))
    # dV/db = -V / sigma; db/dr = total / (4 b) (r / |r| + (r - s) / |r - s|).
    scale = p.v0 / p.sigma * jnp.exp(-b / p.sigma) * total / (4.0 * b)
    fx, fy = scale * (ux + wx), scale * (uy + wy)
    # In view when the other lies within the cone around the heading: heading . (-f) >= |f| cos.
    toward = -(heading_x[:, None] * fx + heading_y[:, None] * fy)
    in_view = _flag(toward >= safe_norm(fx, fy) * p.fov_cos)
    weight = weight * (p.fov_out_weight + (1.0 - p.fov_out_weight) * in_view)
    return jnp.sum(weight * fx, axis=1), jnp.sum(weight * fy, axis=1)


def exponential_wall_force(
    away_x: Array, away_y: Array, valid: Array, radius: Array, p: SocialForceParams
) -> tuple[Array, Array]:
    """Moussaid-form obstacle term summed over obstacles: ``omega exp(-(d - r) / sigma)`` along
    the unit vector away from each, for obstacles with clearance ``d - r`` under the threshold.

    ``away [H, W]`` are vectors from each obstacle (its nearest point, or a sampled point) to each
    pedestrian, ``valid [W]`` or ``[H, W]`` masks padding (and walls out of range),
    ``radius [H]`` (m) the pedestrians' radii.
    """
    ux, uy, dist = unit(away_x, away_y)
    clearance = dist - radius[:, None]
    near = _flag(jnp.atleast_2d(valid) & (clearance < p.obstacle_threshold))
    magnitude = near * p.obstacle_strength * jnp.exp(-clearance / p.obstacle_sigma)
    return jnp.sum(magnitude * ux, axis=1), jnp.sum(magnitude * uy, axis=1)


def helbing_wall_force(
    away_x: Array, away_y: Array, valid: Array, p: SocialForceParams
) -> tuple[Array, Array]:
    """Helbing-Molnar boundary term ``-grad U0 exp(-|r| / R)`` summed over walls ``[W]``, with
    ``r`` from each wall's nearest point to the pedestrian (``away [H, W]``; ``valid [W]`` or
    ``[H, W]``)."""
    ux, uy, dist = unit(away_x, away_y)
    magnitude = jnp.atleast_2d(_flag(valid)) * p.u0 / p.wall_range * jnp.exp(-dist / p.wall_range)
    return jnp.sum(magnitude * ux, axis=1), jnp.sum(magnitude * uy, axis=1)


def cap_speed(vx: Array, vy: Array, max_speed: Array) -> tuple[Array, Array]:
    """Scale velocities ``[H]`` down to at most ``max_speed`` (m/s)."""
    speed = safe_norm(vx, vy)
    factor = jnp.where(speed > max_speed, max_speed / jnp.maximum(speed, _TINY), 1.0)
    return vx * factor, vy * factor
