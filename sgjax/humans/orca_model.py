"""ORCA pedestrians (``make(..., human_model="orca")``): each pedestrian takes the ORCA velocity
(:mod:`sgjax.kernels.orca`) toward its next waypoint among its nearest neighbours, as CrowdNav's,
CrowdNav++'s and SocNavGym's simulated humans do.

Per pedestrian and sub-step of ``dt`` s:

* preferred velocity: ``desired_speed`` (m/s) toward the target waypoint (slowing within one
  step of it), the speed limit ``desired_speed`` (an ORCA agent never walks faster than it
  prefers);
* neighbours: the ``HumanConfig.orca_neighbors`` nearest of the other active pedestrians
  (reciprocal, share 1/2) and the robots in the world (share ``OrcaParams.robot_share``: 1, the
  pedestrian does all the avoiding, for robots that do not run ORCA; parked robots are static,
  share 1; none at all when ``robot_share`` is 0, humans that do not see robots), with
  ``OrcaParams.time_horizon``;
* walls: the ``HumanConfig.orca_walls`` nearest segments with
  ``OrcaParams.obstacle_time_horizon`` (:func:`sgjax.kernels.orca.wall_lines`: a straight wall
  beside
  the pedestrian is the exact half-plane of its velocity obstacle, a wall's end a static point;
  RVO2 builds its lines from polygon obstacles instead), and the swept wall clamp of
  :func:`sgjax.humans.pedestrians.move_humans` keeps every pedestrian out of every wall whatever
  ORCA asks.

The velocity is returned as the force per unit mass that reaches it in one sub-step,
``(v_orca - v) / dt``, so pedestrians of every model share one integrator. Differentiable
almost everywhere: the program's active set, the nearest-neighbour choice and the leg/cut-off
choice switch discontinuously (``jax.grad`` is finite but piecewise).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.humans.near_walls import nearest_walls_in_range
from sgjax.humans.neighbors import Each, Pairs, every_body
from sgjax.humans.replay import walking_target
from sgjax.kernels.geometry import safe_norm
from sgjax.kernels.neighbor_grid import pad_row
from sgjax.kernels.orca import nearest_bodies, orca_velocity, wall_lines
from sgjax.maps.arrays import MapArrays


@struct.dataclass
class OrcaParams:
    """ORCA pedestrian constants (scalars; batch them for a sweep). Defaults: CrowdNav's ORCA
    humans (RVO2's ``timeHorizon`` and ``timeHorizonObst`` of 5 s)."""

    time_horizon: Array | float = 5.0  # s: how far ahead other bodies are avoided
    obstacle_time_horizon: Array | float = 5.0  # s: the same for walls
    robot_share: Array | float = 1.0  # avoidance a pedestrian takes from a moving robot


def orca_forces(
    hp, m: MapArrays, humans, robot_x: Array, robot_y: Array, robot_vx: Array,
    robot_vy: Array, robot_in_world: Array, robot_moving: Array, robot_radius: Array,
    dt: Array, neighbors: int, walls: int,
    find: Each | None = None, wall_range: float | None = None,
) -> tuple[Array, Array, Array]:
    """``(fx, fy)`` ``[H]`` (m/s^2): the change to each pedestrian's ORCA velocity over ``dt``
    s, and the cell lists' overflow (int32). ``hp``:
    :class:`~sgjax.humans.pedestrians.HumanParams`; ``humans``: ``HumanState``; robots are
    ``[R]`` arrays; ``neighbors`` and ``walls`` (static) bound the lines per pedestrian;
    ``find``: how the pedestrians meet the bodies (``HumanConfig.each``, whose range is RVO2's
    ``neighborDist``; ``None``: every body)."""
    h, p = humans, hp.orca
    num = h.x.shape[0]
    tx, ty = walking_target(m, h)
    gx, gy = tx - h.x, ty - h.y
    distance = safe_norm(gx, gy)
    speed = jnp.minimum(h.desired_speed, distance / dt)
    scale = speed / jnp.maximum(distance, 1e-9)
    pref_x, pref_y = gx * scale, gy * scale

    # Every body a pedestrian may avoid: pedestrians then robots, [H, H + R].
    bx = jnp.concatenate([h.x, robot_x])
    by = jnp.concatenate([h.y, robot_y])
    moving = robot_moving & robot_in_world
    bvx = jnp.concatenate([h.vx, jnp.where(moving, robot_vx, 0.0)])
    bvy = jnp.concatenate([h.vy, jnp.where(moving, robot_vy, 0.0)])
    bradius = jnp.concatenate([jnp.broadcast_to(hp.radius, h.x.shape), robot_radius])
    robot_share = jnp.where(moving, p.robot_share, 1.0)
    share = jnp.concatenate([jnp.full(h.x.shape, 0.5), robot_share])
    present = jnp.concatenate([h.active, robot_in_world & (p.robot_share > 0.0)])

    def nearest(pairs: Pairs, x: Array, y: Array) -> tuple[Array, Array]:
        near, valid = nearest_bodies(x, y, pairs.gather(bx), pairs.gather(by),
                                     pairs.weight > 0.0, neighbors)
        if pairs.index is not None:  # places in each pedestrian's list -> body rows
            near = jnp.take_along_axis(pairs.index, near, axis=1)
        return near, valid

    (near, near_valid), overflow = (find or every_body(num))(
        nearest, bx, by, present.astype(jnp.float32))
    # the padding row a short list points at (never valid)
    bx, by, bvx, bvy, bradius, share = (pad_row(a, 0.0) for a in
                                        (bx, by, bvx, bvy, bradius, share))
    # the `walls` nearest segments (within `wall_range`, through the map's cell lists)
    wall_near, wall_valid = nearest_walls_in_range(h.x, h.y, m, walls, wall_range)

    def one(i: Array) -> tuple[Array, Array]:
        idx, w = near[i], wall_near[i]
        lines = wall_lines(h.x[i], h.y[i], h.vx[i], h.vy[i], hp.radius, m.wall_x1[w],
                           m.wall_y1[w], m.wall_x2[w], m.wall_y2[w], wall_valid[i],
                           p.obstacle_time_horizon, dt)
        return orca_velocity(h.x[i], h.y[i], h.vx[i], h.vy[i], hp.radius, pref_x[i],
                             pref_y[i], h.desired_speed[i], bx[idx], by[idx], bvx[idx],
                             bvy[idx], bradius[idx], share[idx], near_valid[i],
                             p.time_horizon, dt, walls=lines)

    vx, vy = jax.vmap(one)(jnp.arange(num))
    vx, vy = jnp.where(h.active, vx, 0.0), jnp.where(h.active, vy, 0.0)
    return (vx - h.vx) / dt, (vy - h.vy) / dt, overflow
