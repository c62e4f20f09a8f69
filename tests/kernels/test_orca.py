"""ORCA (sgjax/kernels/orca.py): the construction against hand-worked cases and a brute-force
velocity
obstacle, the solver against scipy's constrained minimiser, and the dense fallback."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import minimize

from sgjax.kernels.orca import orca_lines, orca_velocity, solve

TAU, DT = 4.0, 0.1


def agents_velocities(positions, velocities, radius, prefs, max_speed, tau=TAU):
    """Every agent's ORCA velocity against all the others (reciprocal)."""
    p = jnp.asarray(positions, jnp.float32)
    v = jnp.asarray(velocities, jnp.float32)
    pref = jnp.asarray(prefs, jnp.float32)
    n = p.shape[0]

    def one(i):
        valid = jnp.arange(n) != i
        return orca_velocity(p[i, 0], p[i, 1], v[i, 0], v[i, 1], radius, pref[i, 0],
                             pref[i, 1], max_speed, p[:, 0], p[:, 1], v[:, 0], v[:, 1],
                             jnp.full(n, radius), jnp.full(n, 0.5), valid, tau, DT)

    vx, vy = jax.jit(jax.vmap(one))(jnp.arange(n))
    return np.stack([np.asarray(vx), np.asarray(vy)], axis=1)


def test_two_agents_head_on_give_the_hand_worked_velocities():
    """A at (-2, 0) moving +x at 1 m/s, B at (2, 0) moving -x, radii 0.5, tau 4 s.
    Relative position p = (4, 0), relative velocity v = (2, 0), combined radius r = 1; the
    cut-off centre is p / tau = (1, 0) and w = v - p / tau = (1, 0) with w . p = 4 > 0, so v is
    projected on a leg (the right one: det(p, w) = 0). Leg length sqrt(16 - 1) = sqrt(15);
    right-leg direction -(4 sqrt15, -4) / 16 = (-sqrt15/4, 1/4); v . d = -sqrt15/2, so
    u = (v . d) d - v = (15/8 - 2, -sqrt15/8) = (-1/8, -sqrt15/8), |u| = 1/2. A's half-plane
    passes through v_A + u/2 = (15/16, -sqrt15/16) with normal u/|u|, and its preferred
    velocity (its current one) lies outside it by |u|/2: A takes (15/16, -sqrt15/16) and, by
    symmetry, B (-15/16, sqrt15/16). Each veers to its own right."""
    got = agents_velocities([[-2, 0], [2, 0]], [[1, 0], [-1, 0]], 0.5,
                            [[1, 0], [-1, 0]], 1.0)
    s = math.sqrt(15)
    np.testing.assert_allclose(got, [[15 / 16, -s / 16], [-15 / 16, s / 16]], atol=1e-5)


def in_truncated_vo(p, v, r, tau):
    """Whether relative velocity v reaches the disc of radius r around p within tau."""
    # |p - v t| < r for some t in [0, tau].
    a, b, c = v @ v, -2 * (p @ v), p @ p - r * r
    if c < 0:
        return True
    if a == 0:
        return False
    disc = b * b - 4 * a * c
    if disc < 0:
        return False
    t = (-b - math.sqrt(disc)) / (2 * a)
    return 0 <= t <= tau


@pytest.mark.parametrize("seed", range(6))
def test_the_half_plane_is_the_nearest_way_out_of_the_velocity_obstacle(seed):
    """|u|, the distance from the relative velocity to the truncated velocity obstacle's
    boundary, against a brute-force search of the obstacle on a polar grid."""
    rng = np.random.default_rng(seed)
    while True:
        p = rng.uniform(-3, 3, 2)
        v = rng.uniform(-2, 2, 2)
        r = 0.8
        if np.linalg.norm(p) > r + 0.2 and in_truncated_vo(p, v, r, TAU):
            break
    lines = orca_lines(0.0, 0.0, float(v[0]), float(v[1]), 0.4, float(p[0]), float(p[1]),
                       jnp.zeros(1), jnp.zeros(1), jnp.asarray([0.4]), jnp.ones(1),
                       jnp.ones(1, bool), TAU, DT)
    # share 1: the line passes through v + u, on the boundary, with v on its forbidden side.
    point = np.array([float(lines.px[0]), float(lines.py[0])])
    u = point - v
    best = _brute_distance(p, v, r)
    assert abs(np.linalg.norm(u) - best) < 5e-3, (np.linalg.norm(u), best)
    direction = np.array([float(lines.dx[0]), float(lines.dy[0])])
    assert abs(np.linalg.norm(direction) - 1) < 1e-5
    assert direction[0] * (point - v)[1] - direction[1] * (point - v)[0] > 0  # v forbidden


def _brute_distance(p, v, r):
    """Smallest |d| with v + d outside the truncated velocity obstacle (grid search)."""
    angles = np.linspace(0, 2 * np.pi, 1440, endpoint=False)
    best = np.inf
    for a in angles:
        step = np.array([np.cos(a), np.sin(a)])
        lo, hi = 0.0, 4.0
        if in_truncated_vo(p, v + hi * step, r, TAU):
            continue
        for _ in range(40):  # bisection along the ray (the obstacle is convex)
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if in_truncated_vo(p, v + mid * step, r, TAU) else (lo, mid)
        best = min(best, hi)
    return best


def _reference_solution(lines, pref, max_speed):
    """The same program by scipy's SLSQP: closest to pref, inside the disc and every line."""
    px, py, dx, dy = (np.asarray(getattr(lines, k), float) for k in ("px", "py", "dx", "dy"))
    valid = np.asarray(lines.valid)
    cons = [{"type": "ineq", "fun": lambda x: max_speed ** 2 - x @ x}]
    for k in np.flatnonzero(valid):
        cons.append({"type": "ineq", "fun": lambda x, k=k: -(dx[k] * (py[k] - x[1])
                                                             - dy[k] * (px[k] - x[0]))})
    result = minimize(lambda x: np.sum((x - pref) ** 2), np.zeros(2), constraints=cons,
                      method="SLSQP", options={"ftol": 1e-12, "maxiter": 500})
    assert result.success, result.message
    return result.x


def test_four_agents_crossing_get_the_optimal_permitted_velocities():
    """Four agents 2 m from a common centre, each heading for the opposite side at 1 m/s:
    each answer is the closest permitted velocity to the preferred one (scipy's SLSQP on the
    same half-planes and disc), satisfies every half-plane, and the four are the same answer
    turned by 90 degrees (the scene's symmetry)."""
    positions = np.array([[-2, 0], [0, -2], [2, 0], [0, 2]], float)
    velocities = -positions / 2
    radius, max_speed = 0.3, 1.0
    got = agents_velocities(positions, velocities, radius, velocities, max_speed)
    for i in range(4):
        valid = jnp.arange(4) != i
        lines = orca_lines(positions[i, 0], positions[i, 1], velocities[i, 0],
                           velocities[i, 1], radius, jnp.asarray(positions[:, 0]),
                           jnp.asarray(positions[:, 1]), jnp.asarray(velocities[:, 0]),
                           jnp.asarray(velocities[:, 1]), jnp.full(4, radius),
                           jnp.full(4, 0.5), valid, TAU, DT)
        np.testing.assert_allclose(got[i], _reference_solution(lines, velocities[i], max_speed),
                                   atol=1e-4)
        px, py, dx, dy = (np.asarray(getattr(lines, k)) for k in ("px", "py", "dx", "dy"))
        slack = dx * (py - got[i, 1]) - dy * (px - got[i, 0])
        assert np.all(slack[np.asarray(valid)] <= 1e-5), slack
        assert np.linalg.norm(got[i]) <= max_speed + 1e-6
    turn = np.array([[0, -1], [1, 0]])  # +90 degrees: agent k's scene is agent k+1's
    for i in range(4):
        np.testing.assert_allclose(turn @ got[i], got[(i + 1) % 4], atol=1e-5)
    assert np.all(np.linalg.norm(got - velocities, axis=1) > 0.05)  # everybody changed course


def test_no_permitted_velocity_falls_back_to_the_least_violation():
    """Boxed in by six agents rushing at it, no velocity satisfies every half-plane: the
    answer is finite, within the speed limit, and violates no line by more than staying put
    would."""
    angles = np.linspace(0, 2 * np.pi, 6, endpoint=False)
    ring = np.stack([np.cos(angles), np.sin(angles)], 1) * 0.9
    positions = np.concatenate([[[0.0, 0.0]], ring])
    velocities = np.concatenate([[[0.5, 0.0]], -ring])
    got = agents_velocities(positions, velocities, 0.4, velocities, 1.0)
    assert np.all(np.isfinite(got)) and np.all(np.linalg.norm(got, axis=1) <= 1.0 + 1e-5)
    lines = orca_lines(0.0, 0.0, 0.5, 0.0, 0.4, jnp.asarray(positions[:, 0]),
                       jnp.asarray(positions[:, 1]), jnp.asarray(velocities[:, 0]),
                       jnp.asarray(velocities[:, 1]), jnp.full(7, 0.4), jnp.full(7, 0.5),
                       jnp.arange(7) != 0, TAU, DT)

    def worst(v):
        px, py, dx, dy = (np.asarray(getattr(lines, k)) for k in ("px", "py", "dx", "dy"))
        return np.max((dx * (py - v[1]) - dy * (px - v[0]))[1:])

    assert worst(got[0]) > 0  # infeasible indeed
    assert worst(got[0]) <= worst(np.zeros(2)) + 1e-5
    vx, vy = solve(lines, jnp.asarray(0.5), jnp.asarray(0.0), jnp.asarray(1.0))
    np.testing.assert_allclose([float(vx), float(vy)], got[0], atol=1e-6)


def test_agrees_with_rvo2_on_a_crossing_scene():
    """The reference implementation (RVO2, through the pyrvo bindings, a test-only
    dependency): eight agents crossing a 3 m circle, 100 steps; at every step each agent's new
    velocity from the same state agrees to 1e-5 m/s (RVO2's state drives both; no obstacles:
    sgjax approximates walls by their nearest points, RVO2 builds polygon obstacles)."""
    pyrvo = pytest.importorskip("pyrvo")
    n, radius, max_speed, dt = 8, 0.3, 1.0, 0.1
    rng = np.random.default_rng(0)
    angle = np.linspace(0, 2 * np.pi, n, endpoint=False)
    position = np.stack([np.cos(angle), np.sin(angle)], 1) * 3.0 + rng.uniform(-0.2, 0.2, (n, 2))
    velocity = rng.uniform(-0.5, 0.5, (n, 2))
    goal = -position
    sim = pyrvo.RVOSimulator()
    sim.set_time_step(dt)
    sim.set_agent_defaults(100.0, n, TAU, TAU, radius, max_speed)
    for i in range(n):
        sim.add_agent(tuple(position[i]))
        sim.set_agent_velocity(i, tuple(velocity[i]))

    @jax.jit
    def ours(p, v, pref):
        def one(i):
            return orca_velocity(p[i, 0], p[i, 1], v[i, 0], v[i, 1], radius, pref[i, 0],
                                 pref[i, 1], max_speed, p[:, 0], p[:, 1], v[:, 0], v[:, 1],
                                 jnp.full(n, radius), jnp.full(n, 0.5), jnp.arange(n) != i,
                                 TAU, dt)

        return jnp.stack(jax.vmap(one)(jnp.arange(n)), axis=1)

    worst = 0.0
    for _ in range(100):
        to_goal = goal - position
        left = np.linalg.norm(to_goal, axis=1, keepdims=True)
        pref = to_goal / np.maximum(left, 1e-9) * np.minimum(max_speed, left)
        for i in range(n):
            sim.set_agent_pref_velocity(i, tuple(pref[i]))
        mine = np.asarray(ours(*(jnp.asarray(a, jnp.float32) for a in (position, velocity,
                                                                        pref))))
        sim.do_step()
        velocity = np.array([sim.get_agent_velocity(i).to_tuple() for i in range(n)])
        position = np.array([sim.get_agent_position(i).to_tuple() for i in range(n)])
        worst = max(worst, float(np.abs(mine - velocity).max()))
    assert worst < 1e-5, worst
    assert np.linalg.norm(position - goal, axis=1).max() < 1.0  # the scene did resolve


def _random_scene(key, count=9):
    """An agent at the origin among ``count`` random neighbours (some overlapping, some moving
    at it): feasible and infeasible programs alike."""
    k = jax.random.split(key, 5)
    positions = jax.random.uniform(k[0], (count, 2), minval=-1.6, maxval=1.6)
    velocities = jax.random.uniform(k[1], (count, 2), minval=-1.0, maxval=1.0)
    pref = jax.random.uniform(k[2], (2,), minval=-1.5, maxval=1.5)
    valid = jax.random.uniform(k[3], (count,)) > 0.2
    own = jax.random.uniform(k[4], (2,), minval=-0.8, maxval=0.8)
    return positions, velocities, pref, valid, own


@pytest.mark.parametrize("seed", range(4))
def test_the_solvers_gradient_is_the_gradient_through_its_loops(seed):
    """The closed form of the active constraints differentiates as automatic differentiation
    through the programs' loops does (``_tracked_solve``, the same solver without the rule),
    with respect to every input, over 64 random scenes per seed, infeasible ones included."""
    from sgjax.kernels.orca import _tracked_solve

    def velocity(solver, positions, velocities, pref, valid, own, tau, speed):
        lines = orca_lines(0.0, 0.0, own[0], own[1], 0.3, positions[:, 0], positions[:, 1],
                           velocities[:, 0], velocities[:, 1], jnp.full(len(valid), 0.3),
                           jnp.full(len(valid), 0.5), valid, tau, DT)
        vx, vy = solver(lines, pref[0], pref[1], speed)[:2]
        return jnp.stack([vx, vy])

    def jacobians(solver):
        return jax.jit(jax.vmap(lambda *a: jax.jacrev(
            lambda p, v, pr, o, t, s: velocity(solver, p, v, pr, a[3], o, t, s),
            argnums=(0, 1, 2, 3, 4, 5))(*a[:3], *a[4:])))

    keys = jax.random.split(jax.random.key(seed), 64)
    positions, velocities, pref, valid, own = jax.vmap(_random_scene)(keys)
    tau, speed = jnp.full(64, TAU), jnp.full(64, 1.2)
    args = (positions, velocities, pref, valid, own, tau, speed)
    values = jax.vmap(lambda *a: velocity(solve, *a))(*args)
    loops = jax.vmap(lambda *a: velocity(_tracked_solve, *a))(*args)
    np.testing.assert_array_equal(np.asarray(values), np.asarray(loops))
    rule, through = jacobians(solve)(*args), jacobians(_tracked_solve)(*args)
    for got, want in zip(jax.tree.leaves(rule), jax.tree.leaves(through), strict=True):
        assert np.all(np.isfinite(np.asarray(got)))
        np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=2e-4, atol=2e-4)
    # the scenes exercise both programs: some need the fallback, most do not
    from sgjax.kernels.orca import _program

    def failed(positions, velocities, pref, valid, own, tau, speed):
        lines = orca_lines(0.0, 0.0, own[0], own[1], 0.3, positions[:, 0], positions[:, 1],
                           velocities[:, 0], velocities[:, 1], jnp.full(len(valid), 0.3),
                           jnp.full(len(valid), 0.5), valid, tau, DT)
        return _program(lines, speed, pref[0], pref[1], False)[2] < len(valid)

    infeasible = np.asarray(jax.vmap(failed)(*args))
    assert 0 < infeasible.sum() < 64
