"""Pedestrians: spawning, invariants, behaviour, determinism, jit and retracing, force laws."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jaxprs import equations, traced_in

import sgjax
from sgjax.humans import HumanState, SocialForceParams
from sgjax.humans.forces import helbing_interaction, helbing_wall_force
from sgjax.kernels.geometry import point_segment_distance, point_segment_offset
from sgjax.maps import parse_map

DT = 0.1


@jax.jit  # one program where called outside jit, not a compile per operation
def _wall_distance(m, x, y):
    d = point_segment_distance(x[..., None], y[..., None], m.wall_x1, m.wall_y1, m.wall_x2,
                               m.wall_y2)
    return jnp.min(jnp.where(m.wall_valid, d, jnp.inf), axis=-1)


def _no_robots(env, params, key):
    """An episode with no robot present (pedestrians only)."""
    none = jnp.zeros(env.max_agents, jnp.int32)
    return env.reset_to(none, none + 1, jnp.zeros(env.max_agents, bool), params, key=key)[1]


def _walkers(m, start_xy, goal_nodes, speed=1.3) -> HumanState:
    """Pedestrians at ``start_xy [H, 2]`` heading for their nearest node, then ``goal_nodes``."""
    pos = jnp.asarray(start_xy, jnp.float32)
    gap = jnp.hypot(m.node_x[None, :] - pos[:, :1], m.node_y[None, :] - pos[:, 1:])
    nearest = jnp.argmin(gap, axis=1).astype(jnp.int32)
    h = pos.shape[0]
    zeros = jnp.zeros(h, jnp.float32)
    return HumanState(x=pos[:, 0], y=pos[:, 1], vx=zeros, vy=zeros, target=nearest,
                      goal=jnp.asarray(goal_nodes, jnp.int32), origin=nearest,
                      desired_speed=jnp.full(h, speed, jnp.float32), active=jnp.ones(h, bool),
                      heading=zeros, omega=zeros)


def _rollout(env, params, state, actions, steps, key=0):
    return _scan_steps(env, params, state, actions, jax.random.split(jax.random.key(key), steps))


@functools.partial(jax.jit, static_argnums=0)
def _scan_steps(env, params, state, actions, keys):
    """A step of ``env`` (static: environments of equal configurations share the program) per
    key under the held ``actions``: the last state and the pedestrians, robots and
    human-collision flags after each step."""
    def body(st, k):
        _, st, _, _, _, info = env.step_env(k, st, actions, params)
        return st, (st.humans, st.robots, info["collision_human"])

    return jax.lax.scan(body, state, keys)


# ------------------------------------------------------------------ spawning and params
@pytest.mark.slow
@pytest.mark.parametrize("scenario", sgjax.registered())
def test_spawns_are_clear_of_walls_robots_and_each_other(scenario):
    env, params = sgjax.make(scenario, num_agents=4, num_humans=30)
    keys = jax.random.split(jax.random.key(3), 32)

    @jax.jit  # the spawns and their gaps in one program, not a compile per operation
    def spawned(keys, params):
        _, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
        h, r = state.humans, state.robots
        pair = jnp.hypot(h.x[:, :, None] - h.x[:, None, :], h.y[:, :, None] - h.y[:, None, :])
        pair = jnp.where(jnp.eye(30, dtype=bool), jnp.inf, pair)
        to_robot = jnp.hypot(h.x[:, :, None] - r.x[:, None, :],
                             h.y[:, :, None] - r.y[:, None, :])
        reach = params.humans.radius + params.robots.radius[None, None, :]
        return (jnp.sum(h.active, axis=1), jnp.min(_wall_distance(params.map, h.x, h.y)),
                jnp.min(pair), jnp.all(jnp.where(r.present[:, None, :], to_robot >= reach, True)))

    active, wall_gap, pair_gap, robots_clear = spawned(keys, params)
    radius = float(params.humans.radius)
    assert bool(jnp.all(active == 30))
    assert float(wall_gap) >= radius
    assert float(pair_gap) >= 2 * radius
    assert bool(robots_clear)


@pytest.mark.slow
def test_num_humans_is_a_param_and_checked():
    env, params = sgjax.make("doorway", num_agents=2, num_humans=5, max_humans=20)
    for n in (0, 5, 20):
        p = params.replace(humans=params.humans.replace(num_humans=jnp.asarray(n)))
        _, state = env.reset(jax.random.key(0), p)
        assert int(jnp.sum(state.humans.active)) == n
    too_many = params.replace(humans=params.humans.replace(num_humans=jnp.asarray(21)))
    with pytest.raises(ValueError, match="num_humans must be in"):
        env.reset(jax.random.key(0), too_many)


def test_make_rejects_bad_pedestrian_options():
    with pytest.raises(ValueError, match=r"human_model must be one of .* got 'orka'"):
        sgjax.make("open", num_humans=2, human_model="orka")
    with pytest.raises(ValueError, match="num_humans must be a non-negative integer"):
        sgjax.make("open", num_humans=-1)
    with pytest.raises(ValueError, match="must not exceed max_humans"):
        sgjax.make("open", num_humans=5, max_humans=2)
    with pytest.raises(ValueError, match="cannot place max_humans=5000"):
        sgjax.make("doorway", num_humans=5000)


# ------------------------------------------------------------------ invariants
@pytest.mark.slow
@pytest.mark.parametrize("scenario,model", [("hallway", "moussaid"), ("office", "moussaid"),
                                            ("intersection", "helbing")])
def test_long_rollouts_stay_finite_capped_and_out_of_walls(scenario, model):
    env, params = sgjax.make(scenario, num_agents=4, num_humans=100, human_model=model)
    num_envs, steps = 2, 1500  # two episodes per case: the run is the cost
    keys = jax.random.split(jax.random.key(7), num_envs)
    _, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    vstep = jax.vmap(env.step, in_axes=(0, 0, 0, None))
    radius = params.humans.radius

    def body(st, k):
        k_act, k_step = jax.random.split(k)
        actions = (jax.random.uniform(k_act, (num_envs, 4)) < 0.3).astype(jnp.int32)
        st = vstep(jax.random.split(k_step, num_envs), st, actions, params)[1]
        h = st.humans
        speed = jnp.hypot(h.vx, h.vy)
        cap = params.humans.max_speed_factor * h.desired_speed
        clearance = _wall_distance(params.map, h.x, h.y) - radius
        finite = jnp.all(jnp.isfinite(h.x) & jnp.isfinite(h.y) & jnp.isfinite(speed))
        return st, (finite, jnp.max(speed - cap), jnp.min(jnp.where(h.active, clearance, 1.0)),
                    jnp.mean(speed, where=h.active))

    _, (finite, over_cap, clearance, mean_speed) = jax.jit(
        lambda s: jax.lax.scan(body, s, jax.random.split(jax.random.key(8), steps)))(state)
    assert bool(jnp.all(finite))
    assert float(jnp.max(over_cap)) <= 1e-5
    assert float(jnp.min(clearance)) >= -1e-4  # never inside a wall (the skin is 1 mm)
    assert float(jnp.mean(mean_speed)) > 0.3  # the crowd keeps moving


# ------------------------------------------------------------------ behaviour
def _wide_corridor():
    """A 3 m wide, 20 m long corridor with nodes down its centre line."""
    nodes = [{"id": i, "position": [float(x), 0.0]} for i, x in enumerate(range(-9, 10, 3))]
    return parse_map({
        "name": "corridor", "description": "3 m wide test corridor",
        "bounds": [-10, -2, 10, 2],
        "walls": [[-10, -1.5, 10, -1.5], [-10, 1.5, 10, 1.5]],
        "nodes": nodes, "edges": [[i, i + 1] for i in range(len(nodes) - 1)],
        "groups": [{"starts": [0], "goals": [len(nodes) - 1]}],
    }, source="corridor")


@pytest.mark.slow
def test_counterflow_groups_get_through_a_corridor():
    """Five pedestrians from each end of a 3 m wide, 20 m long hallway swap ends without
    deadlock or wall contact, within 30 s (measured: about 15 s). (In the shipped hallway's
    1 m corridor two pedestrians cannot pass each other at all: see docs/humans.md.)"""
    env, params = sgjax.make(_wide_corridor(), num_agents=1, num_humans=10,
                             human_goals="return")
    m = params.map
    ys = np.linspace(-1.0, 1.0, 5)
    start = np.concatenate([np.stack([np.full(5, -8.0) - np.arange(5) * 0.3, ys], -1),
                            np.stack([np.full(5, 8.0) + np.arange(5) * 0.3, ys[::-1]], -1)])
    state = _no_robots(env, params, jax.random.key(0))
    state = state.replace(humans=_walkers(m, start, [6] * 5 + [0] * 5))
    _, (humans, _, _) = _rollout(env, params, state, jnp.zeros(1, jnp.int32), 300)
    hx = np.asarray(humans.x)
    crossed = np.concatenate([np.any(hx[:, :5] > 6.0, axis=0), np.any(hx[:, 5:] < -6.0, axis=0)])
    assert crossed.all(), f"stuck: {np.flatnonzero(~crossed)}"
    clearance = _wall_distance(m, humans.x, humans.y) - params.humans.radius
    assert float(jnp.min(clearance)) >= -1e-4


@pytest.mark.slow
@pytest.mark.parametrize("robot_weight,avoids", [(None, True), (0.0, False)])
def test_pedestrians_avoid_a_robot_standing_in_a_corridor(robot_weight, avoids):
    """A robot stands (STOP) in the middle of a corridor; pedestrians walk past it without
    touching it. With robots' social force switched off they walk into it (the test can fail)."""
    env, params = sgjax.make(_wide_corridor(), num_agents=1, num_humans=4)
    if robot_weight is not None:  # None: the default
        # the default's type (not weakly typed): both cases share one compiled rollout
        weight = jnp.full_like(params.humans.robot_weight, robot_weight)
        params = params.replace(humans=params.humans.replace(robot_weight=weight))
    m = params.map
    # The robot stands at x = 1.5 m, between two of the corridor's nodes; STOP keeps it there.
    _, state = env.reset_to(jnp.array([3]), jnp.array([6]), jnp.array([True]), params)
    state = state.replace(robots=state.robots.replace(x=jnp.array([1.5])))
    start = [[-8.0, -0.1], [-8.8, 0.15], [-7.2, 0.05], [-9.0, -0.3]]
    state = state.replace(humans=_walkers(m, start, [6, 6, 6, 6]))
    _, (humans, robots, touching) = _rollout(env, params, state, jnp.ones(1, jnp.int32), 250)
    assert float(jnp.max(jnp.abs(robots.x - 1.5))) < 1e-6  # the robot stood still
    passed = np.asarray(jnp.any(humans.x > 3.5, axis=0))
    if avoids:
        assert not bool(jnp.any(touching))
        assert passed.all()
    else:
        assert bool(jnp.any(touching))


@pytest.mark.slow
def test_robot_pedestrian_contact_is_counted_and_stops_the_robot():
    env, params = sgjax.make(_wide_corridor(), num_agents=1, num_humans=1, action_mode="continuous")
    _, state = env.reset_to(jnp.array([0]), jnp.array([6]), jnp.array([True]), params)
    m = params.map
    # A pedestrian walking straight at the robot, which drives at it at full speed.
    walker = _walkers(m, [[-6.0, 0.0]], [0]).replace(target=jnp.array([0], jnp.int32))
    state = state.replace(humans=walker)
    actions = jnp.array([[1.0, 0.0]])
    onsets = 0
    step = jax.jit(env.step_env)
    for k in range(40):
        _, state, reward, _, _, info = step(jax.random.key(k), state, actions, params)
        onsets = int(state.collisions.human[0])
        if onsets:
            assert bool(info["collision_human"][0])
            assert float(reward[0]) < -5.0  # the collision penalty
            assert float(state.robots.kin.v_forward[0]) == 0.0  # bumper
            break
    assert onsets == 1
    assert int(state.collisions.robot[0]) == 0 and int(state.collisions.wall[0]) == 0


@pytest.mark.slow
def test_planner_sees_pedestrians():
    """Under GO the local planner treats pedestrians as obstacles: a robot driving down the
    corridor at a pedestrian standing on its path goes round it (keeping right), never within
    reach of it."""
    env, params = sgjax.make(_wide_corridor(), num_agents=1, num_humans=1)
    _, state = env.reset_to(jnp.array([0]), jnp.array([6]), jnp.array([True]), params)
    standing = _walkers(params.map, [[-3.0, 0.0]], [2], speed=0.0)
    state = state.replace(humans=standing)
    _, (humans, robots, touching) = _rollout(env, params, state, jnp.zeros(1, jnp.int32), 200)
    assert not bool(jnp.any(touching))
    assert float(jnp.max(jnp.abs(humans.x + 3.0))) < 1e-6  # the pedestrian stood still
    reach = float(params.robots.radius[0] + params.humans.radius)
    gap = jnp.hypot(robots.x[:, 0] + 3.0, robots.y[:, 0]) - reach
    assert float(jnp.min(gap)) > 0.0  # never touched it
    assert float(robots.x[-1, 0]) > -3.0 + reach  # and got past it


# ------------------------------------------------------------------ JAX contracts
def _episode(env, params, key, steps=30):
    """The state after ``steps`` GO steps from ``reset(key)``, as a jitted scan."""
    actions = jnp.zeros(env.max_agents, jnp.int32)

    def body(state, k):
        return env.step(jax.random.fold_in(key, k), state, actions, params)[1], None

    _, state = env.reset(key, params)
    return jax.lax.scan(body, state, jnp.arange(steps))[0]


@pytest.mark.slow
def test_deterministic():
    """Two runs of one jitted episode agree bit for bit (jit = eager with pedestrians is
    tests/terms/test_presets.py::test_rich_terms_jit_equals_eager_and_deterministic)."""
    env, params = sgjax.make("intersection", num_agents=3, num_humans=12)
    key = jax.random.key(11)
    episode = jax.jit(_episode, static_argnums=(0,))
    a = episode(env, params, key)
    b = episode(env, params, key)
    # compared on the host (an eager comparison per array shape is a compile each)
    assert jax.tree.all(jax.tree.map(lambda u, v: np.array_equal(np.asarray(u), np.asarray(v)),
                                     a, b))


@pytest.mark.slow
def test_changing_num_humans_does_not_retrace():
    env, params = sgjax.make("roundabout", num_agents=2, num_humans=4, max_humans=16)
    traces = []

    def run(key, p):
        traces.append(1)
        _, s = env.reset(key, p)
        return env.step(key, s, jnp.zeros(env.max_agents, jnp.int32), p)[1].humans.x

    jitted = jax.jit(run)
    for n in (4, 9, 16, 0):
        p = params.replace(humans=params.humans.replace(num_humans=jnp.asarray(n, jnp.int32)))
        jitted(jax.random.key(n), p).block_until_ready()
    assert len(traces) == 1


def _pedestrian_functions(jaxpr) -> set[str]:
    """The functions of sgjax/humans/ that equations of ``jaxpr`` were traced in."""
    where = (traced_in(eqn) for eqn in equations(jaxpr))
    return {function for file, function in filter(None, where) if "/sgjax/humans/" in file}


def test_a_world_without_pedestrians_traces_none_of_their_code():
    """With ``max_humans == 0`` the reset and the step trace no pedestrian kernel (the paper's
    worlds compile none of it) and hold pedestrians of the shapes and dtypes a world with
    pedestrians has, with no rows; with pedestrians the kernels are traced."""
    key = jax.random.key(0)
    shapes = {}
    for most in (0, 3):
        env, params = sgjax.make("doorway", num_agents=2, num_humans=most, max_humans=most)
        actions = jnp.zeros(env.max_agents, jnp.int32)

        def reset_and_step(k, p, env=env, actions=actions):
            _, state = env.reset(k, p)
            return env.step(k, state, actions, p)[1].humans

        jaxpr = jax.make_jaxpr(reset_and_step)(key, params).jaxpr
        used = _pedestrian_functions(jaxpr)
        if most:
            assert {"spawn_humans", "advance_waypoints"} <= used, used
        else:
            assert all(name.startswith("no_humans") for name in used), used
        shapes[most] = jax.eval_shape(reset_and_step, key, params)
    for none, some in zip(jax.tree.leaves(shapes[0]), jax.tree.leaves(shapes[3]), strict=True):
        assert none.shape == (0,) + some.shape[1:]
        assert (none.dtype, none.weak_type) == (some.dtype, some.weak_type)


@pytest.mark.slow
def test_force_constants_are_differentiable():
    """``jax.grad`` through a rollout with respect to a force constant is finite and non-zero
    (so constants can be fitted)."""
    env, params = sgjax.make("open", num_agents=1, num_humans=6)
    _, state = env.reset(jax.random.key(2), params)

    def spread(strength):
        p = params.replace(humans=params.humans.replace(
            forces=params.humans.forces.replace(social_strength=strength)))

        def body(st, k):
            return env.step_env(jax.random.key(k), st, jnp.zeros(1, jnp.int32), p)[1], None

        st = jax.lax.scan(body, state, jnp.arange(15))[0]
        return jnp.sum(jnp.square(st.humans.x)) + jnp.sum(jnp.square(st.humans.y))

    g = jax.jit(jax.grad(spread))(jnp.asarray(5.1))
    assert bool(jnp.isfinite(g)) and float(jnp.abs(g)) > 0.0


# ------------------------------------------------------------------ force laws
@pytest.mark.slow
def test_helbing_forces_are_minus_the_potential_gradient():
    p = SocialForceParams(fov_out_weight=1.0)
    rng = np.random.default_rng(0)
    # In float64: in float32 the analytic and autodiff gradients round differently near a thin
    # ellipse (0.3% apart for one of these pedestrians), which would hide a real error.
    with jax.enable_x64(True):
        x, y = (jnp.asarray(rng.uniform(-2, 2, 5), jnp.float64) for _ in range(2))
        ox, oy, ovx, ovy = (jnp.asarray(rng.uniform(-2, 2, 3), jnp.float64) for _ in range(4))
        heading = jnp.ones(5, jnp.float64), jnp.zeros(5, jnp.float64)
        interaction = jax.jit(helbing_interaction)  # one program, not a dispatch per operation
        fx, fy = interaction(x, y, *heading, ox, oy, ovx, ovy, jnp.ones((5, 3)), p)

        def potential(px, py):
            rx, ry = px - ox, py - oy
            sx, sy = ovx * p.ellipse_dt, ovy * p.ellipse_dt
            total = jnp.hypot(rx, ry) + jnp.hypot(rx - sx, ry - sy)
            b = 0.5 * jnp.sqrt(total**2 - (sx**2 + sy**2))
            return jnp.sum(p.v0 * jnp.exp(-b / p.sigma))

        gx, gy = jax.jit(jax.vmap(jax.grad(potential, argnums=(0, 1))))(x, y)
    np.testing.assert_allclose(fx, -gx, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(fy, -gy, rtol=1e-6, atol=1e-9)
    # The field of view halves a force from behind.
    behind = SocialForceParams()
    bx, _ = interaction(jnp.zeros(1), jnp.zeros(1), jnp.ones(1), jnp.zeros(1),
                        jnp.array([-0.5]), jnp.zeros(1), jnp.zeros(1), jnp.zeros(1),
                        jnp.ones((1, 1)), behind)
    fx1, _ = interaction(jnp.zeros(1), jnp.zeros(1), jnp.ones(1), jnp.zeros(1),
                         jnp.array([-0.5]), jnp.zeros(1), jnp.zeros(1), jnp.zeros(1),
                         jnp.ones((1, 1)), p)
    np.testing.assert_allclose(bx, 0.5 * fx1, rtol=1e-6)


def test_helbing_wall_force_is_minus_the_potential_gradient():
    p = SocialForceParams()
    wall = [jnp.array([v]) for v in (-1.0, 0.3, 2.0, 0.3)]
    x, y = jnp.array([0.5, -1.5]), jnp.array([0.0, 0.1])

    @jax.jit  # one program, not a dispatch per operation
    def force(x, y):
        ax, ay = point_segment_offset(x[:, None], y[:, None], *wall)
        return helbing_wall_force(ax, ay, jnp.array([True]), p)

    fx, fy = force(x, y)

    def potential(px, py):
        qx, qy = point_segment_offset(px[None, None], py[None, None], *wall)
        return jnp.sum(p.u0 * jnp.exp(-jnp.hypot(qx, qy) / p.wall_range))

    gx, gy = jax.jit(jax.vmap(jax.grad(potential, argnums=(0, 1))))(x, y)
    np.testing.assert_allclose(fx, -gx, rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(fy, -gy, rtol=1e-4, atol=1e-6)
