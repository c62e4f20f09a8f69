"""ORCA pedestrians (``human_model="orca"``): behaviour in the crowd scenes the field uses
(circle crossing, counter-flow in a corridor), walls, robots they do or do not see, and the
environment contract under the model."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from long_runs import jit_for_long_runs
from test_humans import _wide_corridor  # the 3 m wide, 20 m corridor

import sgjax
from sgjax.humans import HumanState
from sgjax.humans.map_params import human_params
from sgjax.humans.pedestrians import HumanConfig, human_forces, move_humans
from sgjax.kernels.geometry import point_segment_distance
from sgjax.kernels.orca import orca_velocity
from sgjax.maps.arrays import compile_map

OVERLAP_TOLERANCE = 0.01  # m: ORCA is collision-free in continuous time; steps of dt leave mm


def test_circle_crossing_of_twenty_resolves_without_overlap():
    """20 agents (radius 0.3 m, 1 m/s) on a 4 m circle, each bound for the opposite point
    (positions jittered by up to 0.1 m, as CrowdNav's circle crossing): all arrive, and no two
    ever overlap by more than the tolerance."""
    n, radius, speed, dt, tau = 20, 0.3, 1.0, 0.1, 5.0
    rng = np.random.default_rng(0)
    angle = np.linspace(0, 2 * np.pi, n, endpoint=False) + rng.uniform(-0.05, 0.05, n)
    start = np.stack([np.cos(angle), np.sin(angle)], 1) * 4.0 + rng.uniform(-0.1, 0.1, (n, 2))
    goal = jnp.asarray(-start)

    def step(carry, _):
        p, v = carry

        def one(i):
            to_goal = goal[i] - p[i]
            left = jnp.linalg.norm(to_goal)
            pref = to_goal / jnp.maximum(left, 1e-9) * jnp.minimum(speed, left / dt)
            return orca_velocity(p[i, 0], p[i, 1], v[i, 0], v[i, 1], radius, pref[0], pref[1],
                                 speed, p[:, 0], p[:, 1], v[:, 0], v[:, 1],
                                 jnp.full(n, radius), jnp.full(n, 0.5), jnp.arange(n) != i,
                                 tau, dt)

        vx, vy = jax.vmap(one)(jnp.arange(n))
        v = jnp.stack([vx, vy], 1)
        p = p + dt * v
        gap = jnp.linalg.norm(p[:, None] - p[None], axis=-1) + 9.0 * jnp.eye(n)
        return (p, v), (jnp.min(gap), jnp.max(jnp.linalg.norm(p - goal, axis=1)))

    _, (gap, remaining) = jax.jit(lambda c: jax.lax.scan(step, c, None, 600))(
        (jnp.asarray(start), jnp.zeros((n, 2))))
    arrived = np.flatnonzero(np.asarray(remaining) < 0.05)
    assert len(arrived), "the crossing never resolved in 60 s"
    assert float(jnp.min(gap)) >= 2 * radius - OVERLAP_TOLERANCE, float(jnp.min(gap))
    assert arrived[0] * dt < 45.0  # measured 34.6 s


def test_counter_flow_in_a_three_metre_corridor_clears():
    """Two groups of six walk at each other down a 3 m corridor (ORCA among themselves, walls
    as obstacles): everybody gets past everybody (5 m beyond the middle) within 30 s, nobody
    enters a wall or overlaps another by more than the tolerance."""
    spec = _wide_corridor()
    m = compile_map(spec)
    n = 12
    config = HumanConfig(max_humans=n, force_model="orca")
    hp = human_params(spec, config, n, 0.25)
    rng = np.random.default_rng(1)
    lane = np.tile(np.linspace(-1.0, 1.0, 3), 4)
    x = np.concatenate([np.repeat([-8.0, -7.2], 3), np.repeat([8.0, 7.2], 3)])
    y = lane + rng.uniform(-0.05, 0.05, n)
    rightward = x < 0
    end = np.where(rightward, 6, 0).astype(np.int32)  # node rows at x = +9 and -9
    humans = HumanState(
        x=jnp.asarray(x, jnp.float32), y=jnp.asarray(y, jnp.float32),
        vx=jnp.zeros(n), vy=jnp.zeros(n), target=jnp.asarray(end), goal=jnp.asarray(end),
        origin=jnp.asarray(end), desired_speed=jnp.full(n, 1.2), active=jnp.ones(n, bool),
        heading=jnp.where(jnp.asarray(rightward), 0.0, jnp.pi), omega=jnp.zeros(n))
    none = jnp.zeros(0)
    dt = 0.05

    def step(h, _):
        fx, fy, _, _, _ = human_forces(config, hp, m, h, none, none, none, none,
                                    jnp.zeros(0, bool), jnp.zeros(0, bool), none, dt)
        h = move_humans(hp, m, h, fx, fy, dt)
        gap = jnp.hypot(h.x[:, None] - h.x[None], h.y[:, None] - h.y[None]) + 9.0 * jnp.eye(n)
        wall = point_segment_distance(h.x[:, None], h.y[:, None], m.wall_x1, m.wall_y1,
                                      m.wall_x2, m.wall_y2)
        wall = jnp.min(jnp.where(m.wall_valid, wall, 9.0))
        return h, (jnp.min(gap), wall, h.x)

    _, (gap, wall, xs) = jax.jit(lambda h: jax.lax.scan(step, h, None, 600))(humans)
    xs = np.asarray(xs)
    done = np.where(rightward, xs > 5.0, xs < -5.0)  # [T, n]: past the other group
    assert done[-1].all(), xs[-1]
    assert np.argmax(done.all(axis=1)) * dt < 30.0  # measured 21.2 s
    # Compiled as users compile (SGJAX_TEST_FULL_OPTIMIZATION=1) the float rounding differs,
    # the 600-step counter-flow takes another path and its closest pair overlaps by 12 mm
    # (0.4881 m), past this tolerance; the suite's fast compile passes. Not yet explained.
    assert float(jnp.min(gap)) >= 0.5 - OVERLAP_TOLERANCE, float(jnp.min(gap))
    assert float(jnp.min(wall)) >= 0.25 - 1e-3, float(jnp.min(wall))


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["hallway", "office"])
def test_long_orca_rollouts_stay_finite_and_out_of_walls(scenario):
    """100 ORCA pedestrians and 4 robots under random GO/STOP for 1000 steps (100 s; one episode
    per map: the run, not the compile, is this test's cost; bench/pedestrian_invariants.py runs
    longer horizons): finite, under the speed cap, never inside a wall. (A dense ORCA crowd may
    jam in a 1 m corridor: its known deadlock; the mean speed is not asserted.)"""
    env, params = sgjax.make(scenario, num_agents=4, num_humans=100, human_model="orca")
    num_envs, steps = 1, 1000
    _, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(jax.random.key(7),
                                                                         num_envs), params)
    vstep = jax.vmap(env.step, in_axes=(0, 0, 0, None))
    m = params.map

    def body(st, k):
        k_act, k_step = jax.random.split(k)
        actions = (jax.random.uniform(k_act, (num_envs, 4)) < 0.3).astype(jnp.int32)
        st = vstep(jax.random.split(k_step, num_envs), st, actions, params)[1]
        h = st.humans
        speed = jnp.hypot(h.vx, h.vy)
        wall = point_segment_distance(h.x[..., None], h.y[..., None], m.wall_x1, m.wall_y1,
                                      m.wall_x2, m.wall_y2)
        clearance = jnp.min(jnp.where(m.wall_valid, wall, 9.0), axis=-1) - params.humans.radius
        finite = jnp.all(jnp.isfinite(h.x) & jnp.isfinite(h.y) & jnp.isfinite(speed))
        over = jnp.max(speed - params.humans.max_speed_factor * h.desired_speed)
        return st, (finite, over, jnp.min(jnp.where(h.active, clearance, 1.0)))

    _, (finite, over, clearance) = jit_for_long_runs(
        lambda s: jax.lax.scan(body, s, jax.random.split(jax.random.key(8), steps)))(state)
    assert bool(jnp.all(finite))
    assert float(jnp.max(over)) <= 1e-5
    assert float(jnp.min(clearance)) >= -1e-4


@pytest.mark.slow
def test_orca_pedestrians_see_robots_or_not():
    """A robot standing 1 m ahead on a pedestrian's way: seen (the default; the pedestrian does
    all the avoiding) it may approach only at about the gap over the time horizon, (1 m - the
    two radii) / 5 s; unseen (``robot_share`` 0) it walks on at its desired speed."""
    env, params = sgjax.make("open", num_agents=1, num_humans=1, human_model="orca")
    _, state = env.reset(jax.random.key(0), params)
    h = state.humans
    target_x, target_y = params.map.node_x[h.target[0]], params.map.node_y[h.target[0]]
    heading = jnp.arctan2(target_y - h.y[0], target_x - h.x[0])
    rx = (h.x[0] + jnp.cos(heading))[None]
    ry = (h.y[0] + jnp.sin(heading))[None]
    zero = jnp.zeros(1)

    def speed(hp):
        fx, fy, _, _, _ = human_forces(env.config.humans, hp, params.map, h, rx, ry, zero, zero,
                                    jnp.ones(1, bool), jnp.ones(1, bool),
                                    params.robots.radius, 0.1)
        return float(jnp.hypot(h.vx[0] + 0.1 * fx[0], h.vy[0] + 0.1 * fy[0]))

    gap = 1.0 - float(params.humans.radius + params.robots.radius[0])
    assert speed(params.humans) == pytest.approx(gap / 5.0, rel=0.05)
    unseen = params.humans.replace(orca=params.humans.orca.replace(robot_share=0.0))
    assert speed(unseen) == pytest.approx(float(h.desired_speed[0]), rel=1e-5)


@pytest.mark.slow
def test_orca_constants_are_params_a_vmap_sweeps_them():
    """Time horizons are params: a vmap over them runs one compiled step per value without
    retracing, and they change the outcome."""
    env, params = sgjax.make("intersection", num_agents=2, num_humans=12, human_model="orca")
    _, state = env.reset(jax.random.key(1), params)
    horizons = jnp.asarray([1.0, 5.0])
    swept = jax.vmap(lambda t: params.replace(humans=params.humans.replace(
        orca=params.humans.orca.replace(time_horizon=t))))(horizons)
    traces = []

    def rollout(p):
        traces.append(1)

        def body(s, k):
            return env.step(k, s, jnp.zeros(2, jnp.int32), p)[1], None

        return jax.lax.scan(body, state, jax.random.split(jax.random.key(2), 60))[0]

    out = jax.jit(jax.vmap(rollout))(swept)
    assert len(traces) == 1
    assert not np.allclose(np.asarray(out.humans.x[0]), np.asarray(out.humans.x[1]))
    assert np.all(np.isfinite(np.asarray(out.humans.x)))


def test_humans_see_robots_is_a_make_option():
    _, seen = sgjax.make("open", num_agents=2, num_humans=3, human_model="orca")
    _, unseen = sgjax.make("open", num_agents=2, num_humans=3, human_model="orca",
                           humans_see_robots=False)
    assert float(seen.humans.orca.robot_share) == 1.0 and float(seen.humans.robot_weight) > 0
    assert float(unseen.humans.orca.robot_share) == 0.0
    assert float(unseen.humans.robot_weight) == 0.0
    with pytest.raises(ValueError, match="humans_see_robots must be True or False"):
        sgjax.make("open", num_humans=3, humans_see_robots="no")
