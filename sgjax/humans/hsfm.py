"""The headed social force model (HSFM; Farina, Fontanelli, Garulli, Giannitrapani and
Prattichizzo, "Walking ahead: the headed social force model", PLoS ONE 2017):
``make(..., human_model="hsfm")``.

A pedestrian has a heading ``theta`` and turns under a torque; it walks forward freely, while
sideways motion is only what the other bodies and walls push it into, damped. Per pedestrian of
mass ``m`` and inertia ``I = m r^2 / 2``, with ``r_f = (cos theta, sin theta)``,
``r_o = (-sin theta, cos theta)`` and body-frame velocity ``(v_f, v_o)``:

* driving force ``f0 = m (v0 e - v) / tau`` (``e``: unit vector to the target waypoint,
  ``v``: world velocity);
* interaction ``fe``: Helbing, Farkas and Vicsek 2000 between bodies, with ``n`` the unit
  vector from the other body, ``t`` its left normal, ``g = max(0, r_i + r_j - d)``:
  ``[A exp((r_i + r_j - d) / B) + k1 g] n + k2 g ((v_j - v_i) . t) t``, and the same from the
  nearest point of every wall (radius ``r_i``, wall at rest);
* forward input ``u_f = (f0 + fe) . r_f``; orthogonal input ``u_o = k_o (fe . r_o) - k_d v_o``;
* torque ``u_theta = -k_theta (theta - theta0) - k_omega omega`` toward ``theta0``, the
  direction of ``e`` (the authors' code), with ``k_theta = I k_lambda |f0|`` and
  ``k_omega = I (1 + alpha) sqrt(k_lambda |f0| / alpha)`` (critically damped for ``alpha``);
* ``m dv_f/dt = u_f``, ``m dv_o/dt = u_o``, ``d theta/dt = omega``, ``I d omega/dt = u_theta``,
  integrated by explicit Euler over each sub-step; the world velocity ``R(theta) (v_f, v_o)``
  then enters the shared integrator (:func:`sgjax.humans.pedestrians.move_humans`: the speed cap and
  the swept wall clamp) as the force that reaches it.

Constants (:class:`HsfmParams`) are those of the authors' launcher (MATLAB, github
francescofarina/HeadedSocialForceModel): ``tau`` 0.5 s, ``A`` 2000 N, ``B`` 0.08 m, ``k1``
1.2e5 kg/s^2, ``k2`` 2.4e5 kg/(m s), ``k_o`` 1, ``k_d`` 500 kg/s, ``k_lambda`` 0.3, ``alpha``
3; mass 80 kg (Social-Navigation-PyEnvs; the launcher draws 60-90 kg). The contact terms are
stiff: ``make`` sub-steps at most 0.02 s with this model. Robots are bodies to it (when seen,
``robot_weight > 0``) of their own radius and velocity. Differentiable except where a contact
starts (``g``) and at the heading wrap.
"""

from __future__ import annotations

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.humans.groups import group_forces
from sgjax.humans.near_walls import wall_offsets
from sgjax.humans.neighbors import Each, Pairs, every_body
from sgjax.humans.replay import walking_target
from sgjax.kernels.geometry import polynomial_atan2, safe_norm, wrap_angle
from sgjax.maps.arrays import MapArrays

MAX_SUBSTEP = 0.02  # s: the longest stable sub-step for the contact terms


@struct.dataclass
class HsfmParams:
    """HSFM constants (scalars; batch them for a sweep). Units in the comments."""

    mass: Array | float = 80.0  # kg
    tau: Array | float = 0.5  # s: relaxation time of the driving force
    strength: Array | float = 2000.0  # N: A, between bodies and from walls
    falloff: Array | float = 0.08  # m: B
    body: Array | float = 1.2e5  # kg/s^2: k1, body compression
    friction: Array | float = 2.4e5  # kg/(m s): k2, sliding friction
    k_orthogonal: Array | float = 1.0  # k_o
    k_damping: Array | float = 500.0  # kg/s: k_d, of sideways motion
    k_lambda: Array | float = 0.3
    alpha: Array | float = 3.0


def pair_force(dx: Array, dy: Array, reach: Array, dvx: Array, dvy: Array,
                p: HsfmParams) -> tuple[Array, Array]:
    """Helbing 2000 force (N) from a body at offset ``-(dx, dy)`` (``d`` = from it to us),
    ``reach`` = the two radii (m), ``(dvx, dvy)`` = its velocity minus ours (m/s)."""
    d = safe_norm(dx, dy)
    nx, ny = dx / jnp.maximum(d, 1e-9), dy / jnp.maximum(d, 1e-9)
    tx, ty = -ny, nx
    g = jnp.maximum(reach - d, 0.0)
    push = p.strength * jnp.exp((reach - d) / p.falloff) + p.body * g
    slide = p.friction * g * (dvx * tx + dvy * ty)
    return push * nx + slide * tx, push * ny + slide * ty


def headed_step(p: HsfmParams, vx: Array, vy: Array, heading: Array, omega: Array,
                f0x: Array, f0y: Array, fex: Array, fey: Array, ex: Array, ey: Array,
                inertia: Array, dt: Array) -> tuple[Array, Array, Array, Array]:
    """The headed dynamics over one explicit Euler step of ``dt`` s (module doc): world
    velocity ``(vx, vy)`` (m/s), ``heading`` (rad) and turn rate ``omega`` (rad/s) under the
    driving force ``f0`` and the interaction ``fe`` (N), toward the unit direction ``e``, for
    pedestrians of moment of inertia ``inertia`` (kg m^2). Returns the new ``(vx, vy, heading,
    omega)``; every array ``[H]``."""
    c, s = jnp.cos(heading), jnp.sin(heading)
    v_f = c * vx + s * vy
    v_o = -s * vx + c * vy
    u_f = (f0x + fex) * c + (f0y + fey) * s
    u_o = p.k_orthogonal * (-fex * s + fey * c) - p.k_damping * v_o
    drive = safe_norm(f0x, f0y)
    k_theta = inertia * p.k_lambda * drive
    # floored under the root: a finite gradient where the driving force vanishes
    k_omega = inertia * (1.0 + p.alpha) * jnp.sqrt(jnp.maximum(p.k_lambda * drive / p.alpha,
                                                               1e-12))
    theta0 = polynomial_atan2(ey, ex)
    u_theta = -k_theta * wrap_angle(heading - theta0) - k_omega * omega
    v_f = v_f + dt * u_f / p.mass
    v_o = v_o + dt * u_o / p.mass
    new_heading = wrap_angle(heading + dt * omega)
    new_omega = omega + dt * u_theta / inertia
    c, s = jnp.cos(new_heading), jnp.sin(new_heading)
    return c * v_f - s * v_o, s * v_f + c * v_o, new_heading, new_omega


def hsfm_update(
    hp, m: MapArrays, humans, robot_x: Array, robot_y: Array, robot_vx: Array,
    robot_vy: Array, robot_in_world: Array, robot_radius: Array, dt: Array,
    find: Each | None = None, wall_range: float | None = None,
) -> tuple[Array, Array, Array, Array, Array]:
    """One explicit Euler sub-step of ``dt`` s for every pedestrian. Returns ``(fx, fy)``
    ``[H]`` (m/s^2: the change of world velocity over ``dt``), the new heading (rad) and
    turn rate (rad/s), and the cell lists' overflow (int32). ``hp``: ``HumanParams``;
    ``humans``: ``HumanState``; robots ``[R]``; ``find``: how the pedestrians meet the bodies
    (``HumanConfig.each``; ``None``: every body)."""
    h, p = humans, hp.hsfm
    num = h.x.shape[0]
    radius = jnp.broadcast_to(hp.radius, h.x.shape)
    inertia = 0.5 * p.mass * radius * radius
    tx, ty = walking_target(m, h)
    ex, ey = tx - h.x, ty - h.y
    dist = safe_norm(ex, ey)
    ex, ey = ex / jnp.maximum(dist, 1e-9), ey / jnp.maximum(dist, 1e-9)
    f0x = p.mass * (h.desired_speed * ex - h.vx) / p.tau
    f0y = p.mass * (h.desired_speed * ey - h.vy) / p.tau

    # Bodies: the other pedestrians and the robots it sees.
    bx = jnp.concatenate([h.x, robot_x])
    by = jnp.concatenate([h.y, robot_y])
    bvx = jnp.concatenate([h.vx, robot_vx])
    bvy = jnp.concatenate([h.vy, robot_vy])
    bradius = jnp.concatenate([radius, robot_radius])
    seen = robot_in_world & (hp.robot_weight > 0.0)
    present = jnp.concatenate([h.active, seen]).astype(jnp.float32)

    def interact(pairs: Pairs, x: Array, y: Array, vx: Array, vy: Array, r: Array
                 ) -> tuple[Array, Array]:
        fx, fy = pair_force(x[:, None] - pairs.gather(bx), y[:, None] - pairs.gather(by),
                             r[:, None] + pairs.gather(bradius, 0.0),
                             pairs.gather(bvx, 0.0) - vx[:, None],
                             pairs.gather(bvy, 0.0) - vy[:, None], p)
        return jnp.sum(pairs.weight * fx, axis=1), jnp.sum(pairs.weight * fy, axis=1)

    (fex, fey), overflow = (find or every_body(num))(interact, bx, by, present, h.vx, h.vy,
                                                     radius)
    # Walls: the nearest point of each (within ``wall_range``, through the map's cell lists)
    ox, oy, acting, _ = wall_offsets(h.x, h.y, m, wall_range)
    wx, wy = pair_force(ox, oy, radius[:, None], -h.vx[:, None], -h.vy[:, None], p)
    valid = acting.astype(jnp.float32)
    fex, fey = fex + jnp.sum(valid * wx, axis=1), fey + jnp.sum(valid * wy, axis=1)
    if hp.groups is not None:  # Moussaid 2010 group forces, per unit mass
        gx, gy = group_forces(hp.groups, h.x, h.y, h.vx, h.vy, tx, ty, h.active)
        fex, fey = fex + p.mass * gx, fey + p.mass * gy

    vx, vy, heading, omega = headed_step(p, h.vx, h.vy, h.heading, h.omega, f0x, f0y, fex,
                                         fey, ex, ey, inertia, dt)
    active = h.active
    return (jnp.where(active, (vx - h.vx) / dt, 0.0), jnp.where(active, (vy - h.vy) / dt, 0.0),
            jnp.where(active, heading, h.heading), jnp.where(active, omega, 0.0),
            overflow)
