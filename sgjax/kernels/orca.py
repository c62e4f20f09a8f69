"""ORCA, optimal reciprocal collision avoidance (van den Berg, Guy, Lin and Manocha 2011), as a
fixed-size JAX program: the velocity obstacles of one agent's neighbours become half-planes of
permitted velocities, and a small linear program picks the permitted velocity closest to the
preferred one.

Construction (the paper's section 5; notation of its reference implementation, RVO2): for an
agent at ``p_a`` with velocity ``v_a`` and radius ``r_a`` and a neighbour at ``p_b``, ``v_b``,
``r_b``, with ``p = p_b - p_a``, ``v = v_a - v_b``, ``r = r_a + r_b`` and time horizon ``tau``,
the truncated velocity obstacle is the cone of relative velocities that reach the disc of
radius ``r`` around ``p`` within ``tau``, cut off by the disc of radius ``r / tau`` around
``p / tau``. ``u`` is the smallest change of ``v`` that leaves it (onto the cut-off circle when
``v`` points back past it, else onto the nearer leg; the right leg on a tie); agents that
overlap already use the cut-off of one time step ``dt`` instead. The permitted half-plane is
``{v' : (v' - (v_a + share * u)) . n >= 0}`` with ``n`` the outward normal at the projection:
``share = 1/2`` for a neighbour that avoids in turn (reciprocal), ``1`` for one that does not
(a parked robot, a robot that ignores pedestrians, a wall point).

Lines are stored as ``point`` and ``direction`` (unit); permitted velocities lie to the left of
the directed line, ``det(direction, point - v') <= 0``.

Solver (:func:`solve`): RVO2's incremental program, with every loop of static length so that it
jits and vmaps: lines are added one at a time; when the current velocity violates line ``i``,
the best velocity on line ``i`` that respects lines ``0..i-1`` and the speed disc replaces it (a
one-dimensional program over a masked vector). This is exact whenever the half-planes and the
disc intersect. When they do not (a dense crowd), a second pass minimises the largest
violation, as RVO2's fallback does (every line soft, walls included). Costs ``K^2`` masked
operations for ``K`` lines per agent, and ``K^3`` for the fallback (both run under ``vmap``).
The derivative of the solution is that of the closed form of its active constraints (a
``custom_jvp``: the loops run once, undifferentiated; a crowd fit's gradient step costs about
two forward passes instead of four). Shapes: ``[K]`` per agent; ``vmap`` over
agents and environments from outside. Units: m, s, m/s.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.kernels.geometry import point_segment_offset

EPS = 1e-6  # parallel-line and zero-length tolerance
TINY = 1e-12  # floor under square roots (their gradient at 0 is infinite)


@struct.dataclass
class Lines:
    """ORCA half-planes, ``[K]`` each: a point on the line and the unit direction (permitted
    velocities to its left), and whether the line takes part."""

    px: Array
    py: Array
    dx: Array
    dy: Array
    valid: Array


def _det(ax: Array, ay: Array, bx: Array, by: Array) -> Array:
    return ax * by - ay * bx


def orca_lines(px: Array, py: Array, vx: Array, vy: Array, radius: Array,
               ox: Array, oy: Array, ovx: Array, ovy: Array, oradius: Array, share: Array,
               valid: Array, tau: Array, dt: Array) -> Lines:
    """Half-planes of one agent (position ``px, py``, velocity ``vx, vy``, ``radius``: scalars)
    against ``K`` neighbours (``ox, oy, ovx, ovy, oradius, share, valid``: ``[K]``), with time
    horizon ``tau`` (s) and step ``dt`` (s). ``share``: the agent's part of the avoidance (1/2
    reciprocal, 1 for a neighbour that does not avoid)."""
    rx, ry = ox - px, oy - py  # p: relative position
    wvx, wvy = vx - ovx, vy - ovy  # v: relative velocity
    r = radius + oradius
    dist_sq = rx * rx + ry * ry
    r_sq = r * r
    apart = dist_sq > r_sq
    # Cut-off centre: p / tau when apart, p / dt when overlapping already.
    inv = jnp.where(apart, 1.0 / tau, 1.0 / dt)
    wx, wy = wvx - inv * rx, wvy - inv * ry
    w_sq = wx * wx + wy * wy
    w_dot_p = wx * rx + wy * ry
    w_len = jnp.sqrt(jnp.maximum(w_sq, EPS * EPS))
    ux_w, uy_w = wx / w_len, wy / w_len
    # Projection on the cut-off circle: direction perpendicular to w, u out along w.
    cut_dx, cut_dy = uy_w, -ux_w
    cut_ux, cut_uy = (r * inv - w_len) * ux_w, (r * inv - w_len) * uy_w
    # Projection on a leg (apart only).
    leg = jnp.sqrt(jnp.maximum(dist_sq - r_sq, TINY))  # TINY, not 0: a finite gradient
    safe_dist_sq = jnp.maximum(dist_sq, EPS)
    left = _det(rx, ry, wx, wy) > 0.0
    leg_dx = jnp.where(left, rx * leg - ry * r, -(rx * leg + ry * r)) / safe_dist_sq
    leg_dy = jnp.where(left, rx * r + ry * leg, -(-rx * r + ry * leg)) / safe_dist_sq
    along = wvx * leg_dx + wvy * leg_dy
    leg_ux, leg_uy = along * leg_dx - wvx, along * leg_dy - wvy
    on_cutoff = (~apart) | ((w_dot_p < 0.0) & (w_dot_p * w_dot_p > r_sq * w_sq))
    dx = jnp.where(on_cutoff, cut_dx, leg_dx)
    dy = jnp.where(on_cutoff, cut_dy, leg_dy)
    ux = jnp.where(on_cutoff, cut_ux, leg_ux)
    uy = jnp.where(on_cutoff, cut_uy, leg_uy)
    return Lines(px=vx + share * ux, py=vy + share * uy, dx=dx, dy=dy,
                 valid=valid & (dist_sq > EPS))


def wall_lines(px: Array, py: Array, vx: Array, vy: Array, radius: Array, ax: Array,
               ay: Array, bx: Array, by: Array, valid: Array, tau: Array, dt: Array) -> Lines:
    """Half-planes of one agent against ``[K]`` static wall segments ``a-b`` (m) with time
    horizon ``tau``. Where the agent's nearest point of a wall lies inside the segment, the
    wall is a straight line as far as the agent can reach and its truncated velocity obstacle
    is exactly a half-plane: velocities toward it faster than ``(d - radius) / tau`` (``d``: the
    distance to it; ``/ dt`` once overlapping). Where the nearest point is an end of the
    segment (a corner), the end is a static point obstacle (:func:`orca_lines`, share 1)."""
    ex, ey = bx - ax, by - ay
    t = jnp.clip(((px - ax) * ex + (py - ay) * ey) / jnp.maximum(ex * ex + ey * ey, EPS),
                 0.0, 1.0)
    qx, qy = ax + t * ex, ay + t * ey
    zero = jnp.zeros_like(qx)
    corner = orca_lines(px, py, vx, vy, radius, qx, qy, zero, zero, zero, jnp.ones_like(qx),
                        valid, tau, dt)
    nx, ny = qx - px, qy - py
    d = jnp.sqrt(jnp.maximum(nx * nx + ny * ny, EPS * EPS))
    nx, ny = nx / d, ny / d  # toward the wall
    limit = (d - radius) / jnp.where(d > radius, tau, dt)  # largest speed toward it
    interior = (t > 0.0) & (t < 1.0)
    # Permitted: v . n <= limit, i.e. to the left of the line through n * limit along (-n_y, n_x).
    return Lines(px=jnp.where(interior, nx * limit, corner.px),
                 py=jnp.where(interior, ny * limit, corner.py),
                 dx=jnp.where(interior, -ny, corner.dx), dy=jnp.where(interior, nx, corner.dy),
                 valid=corner.valid)


def nearest_bodies(x: Array, y: Array, bx: Array, by: Array, pair: Array, k: int
                   ) -> tuple[Array, Array]:
    """For agents at ``x, y`` ``[N]``, the rows of the ``k`` (static) nearest of the bodies
    ``bx, by`` ``[B]`` (or each agent's own ``[N, B]``) that ``pair [N, B]`` allows:
    ``(index [N, k'], valid [N, k'])`` with ``k' = min(k, B - 1)`` (0 when there is no other
    body)."""
    k = max(0, min(k, bx.shape[-1] - 1))
    if not k:
        return jnp.zeros((x.shape[0], 0), jnp.int32), jnp.zeros((x.shape[0], 0), bool)
    bx, by = (bx, by) if bx.ndim == 2 else (bx[None, :], by[None, :])
    gap_sq = jnp.square(bx - x[:, None]) + jnp.square(by - y[:, None])
    _, near = jax.lax.top_k(jnp.where(pair, -gap_sq, -jnp.inf), k)
    return near, jnp.take_along_axis(pair, near, axis=1)


def nearest_walls(x: Array, y: Array, m, k: int) -> tuple[Array, Array]:
    """For agents at ``x, y`` ``[N]``, the rows of the ``k`` (static) nearest valid walls of
    map arrays ``m``: ``(index [N, k'], valid [N, k'])``, ``k' = min(k, W)``."""
    ox, oy = point_segment_offset(x[:, None], y[:, None], m.wall_x1, m.wall_y1, m.wall_x2,
                                  m.wall_y2)
    return nearest_places(ox, oy, jnp.broadcast_to(m.wall_valid, ox.shape), k)


def nearest_places(ox: Array, oy: Array, valid: Array, k: int) -> tuple[Array, Array]:
    """Of the offsets ``ox, oy`` ``[N, K]`` (m) from each agent's candidates, the places of the
    ``k`` (static) nearest ``valid`` ones: ``(place [N, k'], valid [N, k'])``,
    ``k' = min(k, K)``."""
    gap = jnp.where(valid, ox * ox + oy * oy, jnp.inf)
    _, near = jax.lax.top_k(-gap, min(k, gap.shape[1]))
    return near, jnp.take_along_axis(jnp.isfinite(gap), near, axis=1)


def join(*parts: Lines) -> Lines:
    """The lines of several sets, in order."""
    return jax.tree.map(lambda *xs: jnp.concatenate(xs), *parts)


@struct.dataclass
class Active:
    """Where a program's velocity came from (ints; ``-1`` where none): ``line`` the line it was
    last moved onto (``-1``: never moved: the preferred velocity, capped, or the direction at
    full speed), ``kind`` how it sits on that line (0 the target's projection, 1 the left end
    of the line's permitted piece, 2 the right end), ``bound`` the line that ends that piece
    (``-1``: the speed disc)."""

    line: Array
    kind: Array
    bound: Array


NO_ACTIVE = (-1, 0, -1)


def _disc_ends(px: Array, py: Array, dx: Array, dy: Array, max_speed: Array
               ) -> tuple[Array, Array, Array]:
    """Where the line ``p + t d`` meets the speed disc: ``(t_left, t_right, disc)`` (``disc``
    below 0: it misses it)."""
    dot = px * dx + py * dy
    disc = dot * dot + max_speed * max_speed - (px * px + py * py)
    root = jnp.sqrt(jnp.maximum(disc, TINY))
    return -dot - root, -dot + root, disc


def _crossings(lines: Lines, i: Array) -> tuple[Array, Array, Array]:
    """Where line ``i`` crosses every line: ``(t [K], denominator [K], numerator [K])``, ``t``
    along line ``i`` (1 where parallel)."""
    px, py, dx, dy = lines.px[i], lines.py[i], lines.dx[i], lines.dy[i]
    denominator = _det(dx, dy, lines.dx, lines.dy)
    numerator = _det(lines.dx, lines.dy, px - lines.px, py - lines.py)
    parallel = jnp.abs(denominator) <= EPS
    return numerator / jnp.where(parallel, 1.0, denominator), denominator, numerator


def _on_line(lines: Lines, i: Array, others: Array, max_speed: Array, target_x: Array,
             target_y: Array, direction: bool
             ) -> tuple[Array, Array, Array, tuple[Array, Array]]:
    """Best velocity on line ``i`` inside the speed disc and the lines flagged in ``others``
    (``[K]`` bool): the closest to ``target`` or, with ``direction``, the farthest along the
    unit vector ``target``. Returns ``(vx, vy, feasible, (kind, bound))`` (see
    :class:`Active`)."""
    px, py, dx, dy = lines.px[i], lines.py[i], lines.dx[i], lines.dy[i]
    disc_left, disc_right, disc = _disc_ends(px, py, dx, dy, max_speed)
    t, denominator, numerator = _crossings(lines, i)
    parallel = jnp.abs(denominator) <= EPS
    bounds_right = others & ~parallel & (denominator >= 0.0)
    bounds_left = others & ~parallel & (denominator < 0.0)
    right_t = jnp.where(bounds_right, t, jnp.inf)
    left_t = jnp.where(bounds_left, t, -jnp.inf)
    right_line, left_line = jnp.argmin(right_t), jnp.argmax(left_t)
    t_right = jnp.minimum(disc_right, jnp.min(right_t))
    t_left = jnp.maximum(disc_left, jnp.max(left_t))
    right_bound = jnp.where(right_t[right_line] < disc_right, right_line, -1)
    left_bound = jnp.where(left_t[left_line] > disc_left, left_line, -1)
    blocked = jnp.any(others & parallel & (numerator < 0.0))
    feasible = (disc >= 0.0) & (t_left <= t_right) & ~blocked
    if direction:
        right = target_x * dx + target_y * dy > 0.0
        best = jnp.where(right, t_right, t_left)
        kind = jnp.where(right, 2, 1)
    else:
        along = dx * (target_x - px) + dy * (target_y - py)
        best = jnp.clip(along, t_left, t_right)
        kind = jnp.where(along > t_right, 2, jnp.where(along < t_left, 1, 0))
    bound = jnp.where(kind == 2, right_bound, jnp.where(kind == 1, left_bound, -1))
    return px + best * dx, py + best * dy, feasible, (kind, bound)


def _start_velocity(max_speed: Array, target_x: Array, target_y: Array, direction: bool
                    ) -> tuple[Array, Array]:
    """A program's velocity before any line: the direction at full speed, or the target
    capped at ``max_speed``."""
    if direction:
        return target_x * max_speed, target_y * max_speed
    # floored under the root: a finite gradient where the preferred velocity is zero
    speed = jnp.sqrt(jnp.maximum(target_x * target_x + target_y * target_y, EPS * EPS))
    scale = jnp.where(speed > max_speed, max_speed / jnp.maximum(speed, EPS), 1.0)
    return target_x * scale, target_y * scale


def _program(lines: Lines, max_speed: Array, target_x: Array, target_y: Array,
             direction: bool) -> tuple[Array, Array, Array, Active]:
    """The incremental two-dimensional program over every valid line. Returns the velocity,
    the index of the first line it could not satisfy (``K`` when all were) and where the
    velocity came from (:class:`Active`)."""
    count = lines.px.shape[0]
    vx, vy = _start_velocity(max_speed, target_x, target_y, direction)
    index = jnp.arange(count)

    def add(i: Array, carry: tuple) -> tuple:
        vx, vy, failed, active = carry
        violated = lines.valid[i] & (_det(lines.dx[i], lines.dy[i], lines.px[i] - vx,
                                          lines.py[i] - vy) > 0.0)
        nx, ny, feasible, (kind, bound) = _on_line(lines, i, lines.valid & (index < i),
                                                   max_speed, target_x, target_y, direction)
        update = violated & (failed == count)
        ok = update & feasible
        failed = jnp.where(update & ~feasible, i, failed)
        active = jax.tree.map(lambda new, old: jnp.where(ok, new, old),
                              Active(line=i, kind=kind, bound=bound), active)
        return jnp.where(ok, nx, vx), jnp.where(ok, ny, vy), failed, active

    start = Active(*(jnp.asarray(v) for v in NO_ACTIVE))
    return jax.lax.fori_loop(0, count, add, (vx, vy, jnp.asarray(count), start))


def _projected(lines: Lines, i: Array) -> Lines:
    """The lines before ``i`` projected onto the bisectors between each of them and line ``i``
    (RVO2's fallback program runs over these)."""
    count = lines.px.shape[0]
    index = jnp.arange(count)
    dxi, dyi, pxi, pyi = lines.dx[i], lines.dy[i], lines.px[i], lines.py[i]
    determinant = _det(dxi, dyi, lines.dx, lines.dy)
    parallel = jnp.abs(determinant) <= EPS
    same_way = parallel & (dxi * lines.dx + dyi * lines.dy > 0.0)
    along = _det(lines.dx, lines.dy, pxi - lines.px, pyi - lines.py) / jnp.where(
        parallel, 1.0, determinant)
    qx = jnp.where(parallel, 0.5 * (pxi + lines.px), pxi + along * dxi)
    qy = jnp.where(parallel, 0.5 * (pyi + lines.py), pyi + along * dyi)
    bx, by = lines.dx - dxi, lines.dy - dyi
    b_len = jnp.sqrt(jnp.maximum(bx * bx + by * by, EPS * EPS))
    return Lines(px=qx, py=qy, dx=bx / b_len, dy=by / b_len,
                 valid=lines.valid & (index < i) & ~same_way)


def _least_violation(lines: Lines, start: Array, max_speed: Array, vx: Array, vy: Array
                     ) -> tuple[Array, Array, Array, Active]:
    """RVO2's fallback: from line ``start`` on, move the velocity to keep the largest violation
    of any line as small as the speed disc allows (lines before ``start`` were satisfied).
    Returns the velocity, the line whose projected program gave it last (``-1``: never
    moved) and where in that program it came from (:class:`Active`)."""
    count = lines.px.shape[0]

    def relax(i: Array, carry: tuple) -> tuple:
        vx, vy, distance, moved_by, active = carry
        dxi, dyi, pxi, pyi = lines.dx[i], lines.dy[i], lines.px[i], lines.py[i]
        worse = (i >= start) & lines.valid[i] & (_det(dxi, dyi, pxi - vx, pyi - vy) > distance)
        nx, ny, failed, found = _program(_projected(lines, i), max_speed, -dyi, dxi, True)
        keep = failed < count  # numerically infeasible: keep the velocity
        nx, ny = jnp.where(keep, vx, nx), jnp.where(keep, vy, ny)
        moved = worse & ~keep
        vx, vy = jnp.where(worse, nx, vx), jnp.where(worse, ny, vy)
        distance = jnp.where(worse, _det(dxi, dyi, pxi - vx, pyi - vy), distance)
        active = jax.tree.map(lambda new, old: jnp.where(moved, new, old), found, active)
        return vx, vy, distance, jnp.where(moved, i, moved_by), active

    start_active = Active(*(jnp.asarray(v) for v in NO_ACTIVE))
    vx, vy, _, moved_by, active = jax.lax.fori_loop(
        0, count, relax, (vx, vy, jnp.asarray(0.0, vx.dtype), jnp.asarray(-1), start_active))
    return vx, vy, moved_by, active


def _tracked_solve(lines: Lines, pref_x: Array, pref_y: Array, max_speed: Array
                   ) -> tuple[Array, Array, tuple[Active, Array, Active]]:
    """:func:`solve`'s velocity and where it came from: ``(program's Active, the fallback's
    line (-1: the program's velocity stands), the fallback's Active)``."""
    vx, vy, failed, active = _program(lines, max_speed, pref_x, pref_y, False)
    fx, fy, moved_by, fallback = _least_violation(lines, failed, max_speed, vx, vy)
    infeasible = failed < lines.px.shape[0]
    moved_by = jnp.where(infeasible, moved_by, -1)
    return (jnp.where(infeasible, fx, vx), jnp.where(infeasible, fy, vy),
            (active, moved_by, fallback))


def _point_on(lines: Lines, active: Active, max_speed: Array, target_x: Array,
              target_y: Array, direction: bool) -> tuple[Array, Array]:
    """The velocity a program with this :class:`Active` gives, as a smooth function of the
    lines, target and speed: the closed form its derivative is taken of."""
    i, j = jnp.maximum(active.line, 0), jnp.maximum(active.bound, 0)
    px, py, dx, dy = lines.px[i], lines.py[i], lines.dx[i], lines.dy[i]
    disc_left, disc_right, _ = _disc_ends(px, py, dx, dy, max_speed)
    crossing = _crossings(lines, i)[0][j]
    by_line = active.bound >= 0
    t = jnp.where(active.kind == 2, jnp.where(by_line, crossing, disc_right),
                  jnp.where(by_line, crossing, disc_left))
    if not direction:
        t = jnp.where(active.kind == 0, dx * (target_x - px) + dy * (target_y - py), t)
    sx, sy = _start_velocity(max_speed, target_x, target_y, direction)
    moved = active.line >= 0
    return jnp.where(moved, px + t * dx, sx), jnp.where(moved, py + t * dy, sy)


def _smooth_solution(lines: Lines, pref_x: Array, pref_y: Array, max_speed: Array,
                     where: tuple[Active, Array, Active]) -> tuple[Array, Array]:
    """:func:`solve`'s velocity as the closed form of its active constraints ``where``."""
    active, moved_by, fallback = where
    vx, vy = _point_on(lines, active, max_speed, pref_x, pref_y, False)
    i = jnp.maximum(moved_by, 0)
    fx, fy = _point_on(_projected(lines, i), fallback, max_speed, -lines.dy[i], lines.dx[i],
                       True)
    return jnp.where(moved_by >= 0, fx, vx), jnp.where(moved_by >= 0, fy, vy)


@jax.custom_jvp
def solve(lines: Lines, pref_x: Array, pref_y: Array, max_speed: Array) -> tuple[Array, Array]:
    """The velocity (m/s) within ``max_speed`` closest to ``(pref_x, pref_y)`` that every valid
    line permits; the least-violating one when no velocity does (see the module doc).

    Its derivative is that of the closed form of the constraints active at the solution (the
    line it lies on and the line or disc that ends it there, or the fallback's projected line),
    the derivative automatic differentiation through the programs' loops gives, without
    differentiating the loops (their discrete choices are constant almost everywhere)."""
    vx, vy, _ = _tracked_solve(lines, pref_x, pref_y, max_speed)
    return vx, vy


@solve.defjvp
def _solve_jvp(primals: tuple, tangents: tuple) -> tuple:
    lines, pref_x, pref_y, max_speed = primals
    vx, vy, where = _tracked_solve(lines, pref_x, pref_y, max_speed)
    _, (dvx, dvy) = jax.jvp(lambda *p: _smooth_solution(*p, where), primals, tangents)
    return (vx, vy), (dvx, dvy)


def orca_velocity(px: Array, py: Array, vx: Array, vy: Array, radius: Array, pref_x: Array,
                  pref_y: Array, max_speed: Array, ox: Array, oy: Array, ovx: Array,
                  ovy: Array, oradius: Array, share: Array, valid: Array, tau: Array,
                  dt: Array, walls: Lines | None = None) -> tuple[Array, Array]:
    """One agent's ORCA velocity against ``[K]`` neighbours (:func:`orca_lines`) and optional
    wall lines (:func:`wall_lines`), by :func:`solve`."""
    lines = orca_lines(px, py, vx, vy, radius, ox, oy, ovx, ovy, oradius, share, valid, tau, dt)
    if walls is not None:
        lines = join(walls, lines)
    return solve(lines, pref_x, pref_y, max_speed)
