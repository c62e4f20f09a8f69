"""The headed social force model (sgjax/humans/hsfm.py) against its published equations on
hand-built states, and in the environment."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.humans import HumanState
from sgjax.humans.hsfm import hsfm_update
from sgjax.humans.pedestrians import human_forces, move_humans

DT = 0.02


@pytest.fixture(scope="module")
def open_map():
    _, params = sgjax.make("open", num_agents=1, num_humans=2, human_model="hsfm")
    return params


def humans_at(params, xy, velocity, heading, omega=0.0, target_row=None):
    """Pedestrians at ``xy [n, 2]`` heading for node row ``target_row`` (default: the node
    farthest along +x)."""
    m = params.map
    n = len(xy)
    row = int(np.argmax(np.asarray(m.node_x))) if target_row is None else target_row
    xy, velocity = np.asarray(xy, np.float32), np.asarray(velocity, np.float32)
    return HumanState(
        x=jnp.asarray(xy[:, 0]), y=jnp.asarray(xy[:, 1]), vx=jnp.asarray(velocity[:, 0]),
        vy=jnp.asarray(velocity[:, 1]), target=jnp.full(n, row, jnp.int32),
        goal=jnp.full(n, row, jnp.int32), origin=jnp.full(n, row, jnp.int32),
        desired_speed=jnp.full(n, 1.2), active=jnp.ones(n, bool),
        heading=jnp.full(n, heading, jnp.float32), omega=jnp.full(n, omega, jnp.float32))


def update(params, humans):
    none = jnp.zeros(0)
    return hsfm_update(params.humans, params.map, humans, none, none, none, none,
                       jnp.zeros(0, bool), none, DT)[:4]


def unit_to_target(params, h, i=0):
    m = params.map
    ex = float(m.node_x[h.target[i]] - h.x[i])
    ey = float(m.node_y[h.target[i]] - h.y[i])
    norm = math.hypot(ex, ey)
    return ex / norm, ey / norm


def test_a_pedestrian_facing_its_goal_accelerates_straight_at_it(open_map):
    """At rest, facing the target: f0 = m v0 e / tau; u_f = f0 . r_f = m v0 / tau, u_o = 0,
    no torque (theta = theta0): after dt the speed is dt v0 / tau along e, heading unchanged."""
    h = humans_at(open_map, [[0.0, 0.0]], [[0.0, 0.0]], 0.0)
    ex, ey = unit_to_target(open_map, h)
    h = h.replace(heading=jnp.asarray([math.atan2(ey, ex)], jnp.float32))
    fx, fy, heading, omega = update(open_map, h)
    p = open_map.humans.hsfm
    speed = DT * 1.2 / float(p.tau)
    np.testing.assert_allclose([float(fx[0]) * DT, float(fy[0]) * DT], [speed * ex, speed * ey],
                               rtol=1e-4, atol=1e-6)
    assert float(heading[0]) == pytest.approx(math.atan2(ey, ex), abs=1e-6)
    assert float(omega[0]) == pytest.approx(0.0, abs=1e-3)


def test_a_pedestrian_facing_sideways_turns_before_it_walks(open_map):
    """At rest, heading 90 degrees off its target: the driving force lies along r_o, so u_f = 0
    and (no other force) u_o = 0: it does not move. The torque -k_theta (theta - theta0) with
    k_theta = I k_lambda |f0|, I = m r^2 / 2, turns it toward theta0:
    omega' = -dt k_lambda |f0| (pi / 2)."""
    h = humans_at(open_map, [[0.0, 0.0]], [[0.0, 0.0]], 0.0)
    ex, ey = unit_to_target(open_map, h)
    theta0 = math.atan2(ey, ex)
    h = h.replace(heading=jnp.asarray([theta0 + math.pi / 2], jnp.float32))
    fx, fy, heading, omega = update(open_map, h)
    p = open_map.humans.hsfm
    f0 = float(p.mass) * 1.2 / float(p.tau)
    assert abs(float(fx[0])) < 1e-3 and abs(float(fy[0])) < 1e-3  # no step sideways
    assert float(omega[0]) == pytest.approx(-DT * float(p.k_lambda) * f0 * math.pi / 2,
                                            rel=1e-4)
    assert float(heading[0]) == pytest.approx(theta0 + math.pi / 2, abs=1e-6)  # omega was 0
    # With a turn rate already, the damping k_omega = I (1 + alpha) sqrt(k_lambda |f0| / alpha)
    # brakes it: omega' = omega - dt (k_lambda |f0| (theta - theta0) + (1 + alpha)
    # sqrt(k_lambda |f0| / alpha) omega).
    h2 = h.replace(omega=jnp.asarray([-1.0], jnp.float32))
    _, _, heading2, omega2 = update(open_map, h2)
    k_omega_over_i = (1 + float(p.alpha)) * math.sqrt(float(p.k_lambda) * f0 / float(p.alpha))
    expected = -1.0 - DT * (float(p.k_lambda) * f0 * math.pi / 2 - k_omega_over_i)
    assert float(omega2[0]) == pytest.approx(expected, rel=1e-4)
    assert float(heading2[0]) == pytest.approx(theta0 + math.pi / 2 - DT, abs=1e-5)


def test_two_bodies_in_contact_push_and_rub_as_helbing_2000(open_map):
    """Pedestrian i at rest at the origin facing +x, j overlapping it 0.4 m to its east (radii
    0.25 m, g = 0.1 m) and walking north at 1 m/s. On i: n = (-1, 0), t = (0, -1),
    push = A exp(g / B) + k1 g along n, friction k2 g ((v_j - v_i) . t) t = (0, k2 g).
    Facing +x: u_o = k_o fe_y - k_d v_o = k2 g, so v_o' = dt k2 g / m (it is dragged along);
    u_f = f0_x + fe_x."""
    h = humans_at(open_map, [[0.0, 0.0], [0.4, 0.0]], [[0.0, 0.0], [0.0, 1.0]], 0.0)
    fx, fy, _, _ = update(open_map, h)
    p = open_map.humans.hsfm
    g = 0.5 - 0.4
    push = float(p.strength) * math.exp(g / float(p.falloff)) + float(p.body) * g
    rub = float(p.friction) * g
    ex, _ = unit_to_target(open_map, h)
    m = float(p.mass)
    f0x = m * 1.2 * ex / float(p.tau)
    vf = DT * (f0x - push) / m  # heading 0: r_f = +x
    vo = DT * (float(p.k_orthogonal) * rub) / m  # r_o = +y; the driving force is not in u_o
    np.testing.assert_allclose([float(fx[0]) * DT, float(fy[0]) * DT], [vf, vo], rtol=1e-4)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["doorway", "office"])
def test_long_hsfm_rollouts_stay_finite_and_out_of_walls(scenario):
    """100 HSFM pedestrians and 4 robots for 1500 steps (make sub-steps at 0.02 s): finite,
    never inside a wall, and the crowd keeps moving."""
    from sgjax.kernels.geometry import point_segment_distance

    env, params = sgjax.make(scenario, num_agents=4, num_humans=100, human_model="hsfm")
    assert float(params.dt) / env.config.substeps <= 0.02 + 1e-9
    _, state = env.reset(jax.random.key(7), params)
    m = params.map

    def body(st, k):
        k_act, k_step = jax.random.split(k)
        actions = (jax.random.uniform(k_act, (4,)) < 0.3).astype(jnp.int32)
        st = env.step(k_step, st, actions, params)[1]
        h = st.humans
        wall = point_segment_distance(h.x[:, None], h.y[:, None], m.wall_x1, m.wall_y1,
                                      m.wall_x2, m.wall_y2)
        clearance = jnp.min(jnp.where(m.wall_valid, wall, 9.0), axis=1) - params.humans.radius
        finite = jnp.all(jnp.isfinite(h.x) & jnp.isfinite(h.heading) & jnp.isfinite(h.omega))
        return st, (finite, jnp.min(jnp.where(h.active, clearance, 1.0)),
                    jnp.mean(jnp.hypot(h.vx, h.vy), where=h.active))

    _, (finite, clearance, speed) = jax.jit(
        lambda s: jax.lax.scan(body, s, jax.random.split(jax.random.key(8), 1500)))(state)
    assert bool(jnp.all(finite))
    assert float(jnp.min(clearance)) >= -1e-4
    assert float(jnp.mean(speed)) > 0.1


@pytest.mark.parametrize(("model", "field", "value"), [
    ("hsfm", "k_lambda", 0.3), ("orca", "time_horizon", 5.0)])
def test_model_constants_are_differentiable(model, field, value):
    """``jax.grad`` of where the crowd ends up with respect to a model constant is finite (and
    non-zero): constants can be fitted. The gradient goes through the crowd's own update (the
    forces of ``human_forces`` and the wall-clamped move of ``move_humans``, the same calls as
    the step's sub-steps) over 8 sub-steps, beside one robot that stands still. (ORCA's is
    piecewise: the active constraints switch.)"""
    env, params = sgjax.make("open", num_agents=1, num_humans=6, human_model=model)
    _, state = env.reset(jax.random.key(2), params)
    section = "hsfm" if model == "hsfm" else "orca"
    config, robots, dt = env.config.humans, state.robots, params.dt / env.config.substeps
    zero = jnp.zeros_like(robots.x)

    def spread(constant):
        hp = params.humans.replace(**{section: getattr(params.humans, section).replace(
            **{field: constant})})

        def body(humans, _):
            fx, fy, heading, omega, _ = human_forces(
                config, hp, params.map, humans, robots.x, robots.y, zero, zero,
                robots.in_world, robots.moving, params.robots.radius, dt)
            moved = move_humans(hp, params.map, humans, fx, fy, dt)
            return moved.replace(heading=heading, omega=omega), None

        humans = jax.lax.scan(body, state.humans, None, length=8)[0]
        return jnp.sum(jnp.square(humans.x)) + jnp.sum(jnp.square(humans.y))

    g = jax.jit(jax.grad(spread))(jnp.asarray(value))
    assert bool(jnp.isfinite(g)) and float(jnp.abs(g)) > 0.0, g
