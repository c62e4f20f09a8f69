"""Classical continuous-action baselines (sgjax/evaluation/controllers.py): ``orca`` robots pass
each other
in open space without contact, under every kinematic model's limits, stop for a wall, and run
through ``sgjax evaluate`` like any baseline."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.environment.options import MakeOptions
from sgjax.evaluation.controllers import track_velocity
from sgjax.evaluation.policies import load_policy, policy_options


def run_controller(scenario, starts, goals, seconds, robots="socialgym", name="orca"):
    """Robots from node ids ``starts`` to ``goals`` under controller ``name``. Returns
    arrival times (s; inf: never), the smallest gap between two robots (m), collision onsets,
    and the largest speed over each robot's limit (m/s)."""
    spec = sgjax.maps.load(scenario)
    n = len(starts)
    env, params = sgjax.make(spec, num_agents=n, action_mode="continuous", robots=robots)
    policy = load_policy(name, env)
    rows = [jnp.array([spec.index_of(i) for i in ids]) for ids in (starts, goals)]
    _, state = env.reset_to(rows[0], rows[1], jnp.ones(n, bool), params)
    steps = round(seconds / float(params.dt))
    radius, limit = params.robots.radius, params.robots.max_speed

    @jax.jit
    def run(state):
        def body(state, t):
            obs = env.observe(state, params)
            actions = policy(obs, jax.random.key(0), state, params)
            _, state, *_ = env.step_env(jax.random.key(0), state, actions, params)
            r = state.robots
            gap = (jnp.hypot(r.x[:, None] - r.x[None, :], r.y[:, None] - r.y[None, :])
                   - radius[:, None] - radius[None, :])
            meet = r.in_world[:, None] & r.in_world[None, :] & ~jnp.eye(n, dtype=bool)
            speed = jnp.hypot(r.kin.v_forward, r.kin.v_lateral)
            return state, (r.succeeded, jnp.min(jnp.where(meet, gap, jnp.inf)),
                           jnp.max(speed - limit))

        return jax.lax.scan(body, state, jnp.arange(steps))

    state, (arrived, gaps, over) = run(state)
    arrived = np.asarray(arrived)
    when = np.where(arrived.any(axis=0), (arrived.argmax(axis=0) + 1) * float(params.dt), np.inf)
    return when, float(np.min(gaps)), np.asarray(state.collisions.robot), float(np.max(over))


@pytest.mark.slow
@pytest.mark.parametrize(("robots", "starts", "goals"), [
    ("socialgym", [12, 36], [36, 12]),  # differential drive, head-on through the middle
    ("socialgym", [0, 12, 24, 36], [24, 36, 0, 12]),  # four ends swapped through one point
    ("cobot", [0, 12, 24, 36], [24, 36, 0, 12]),  # omnidirectional
    ("automata", [12, 36], [36, 12]),  # Ackermann
])
def test_orca_robots_pass_each_other_in_the_open(robots, starts, goals):
    """Every robot arrives within 25 s, no two touch, no speed limit is exceeded."""
    when, gap, collisions, over = run_controller("open", starts, goals, 25.0, robots)
    assert np.all(when <= 25.0), when
    assert gap > 0.0 and not collisions.any(), (gap, collisions)
    assert over <= 1e-5


@pytest.mark.slow
@pytest.mark.parametrize("name", ["dwa", "social_force"])
def test_dwa_and_social_force_robots_pass_head_on_in_the_open(name):
    """Two differential-drive robots head-on through the open map's centre: both arrive within
    25 s, they never touch, no speed limit is exceeded."""
    when, gap, collisions, over = run_controller("open", [12, 36], [36, 12], 25.0, name=name)
    assert np.all(when <= 25.0), when
    assert gap > 0.0 and not collisions.any(), (gap, collisions)
    assert over <= 1e-5


@pytest.mark.slow
@pytest.mark.parametrize("name", ["orca", "dwa", "social_force"])
def test_a_robot_facing_a_wall_stops_short_of_it(name):
    """A robot in the hallway's west room, 1.2 m from the wall x = -3 (which runs from y = 0.5
    to 6), whose route runs straight through that wall: it stops short of the wall (ORCA's
    wall half-plane allows approaching at the gap over its horizon; DWA admits only arcs it can
    stop on; the wall force pushes back)."""
    env, params = sgjax.make("hallway", num_agents=1, action_mode="continuous")
    policy = load_policy(name, env)
    _, state = env.reset(jax.random.key(0), params)
    x_wall, y = -3.0, 3.0
    r = state.robots
    state = state.replace(robots=r.replace(x=jnp.asarray([x_wall - 1.2]), y=jnp.asarray([y]),
                                           kin=r.kin.replace(heading=jnp.zeros(1))))
    route = state.route  # a route straight through the wall, to 5 m beyond it
    through = jnp.full_like(route.x, x_wall + 5.0).at[:, 0].set(x_wall - 1.2)
    state = state.replace(route=route.replace(x=through, y=jnp.full_like(route.y, y)),
                          progress=jnp.zeros(1))
    step = jax.jit(env.step_env)
    act = jax.jit(policy)
    closest = np.inf
    for t in range(80):
        actions = act(None, jax.random.key(t), state, params)
        _, state, *_ = step(jax.random.key(t), state, actions, params)
        closest = min(closest, x_wall - float(state.robots.x[0]) - float(params.robots.radius[0]))
    assert closest > 0.0, closest  # never touched
    assert int(state.collisions.wall[0]) == 0
    assert abs(float(state.robots.kin.v_forward[0])) < 0.05  # and stopped
    if name == "orca":
        assert closest < 0.6  # ORCA comes close first (DWA stops where no arc is admissible)


@pytest.mark.parametrize("name", ["orca", "dwa", "social_force"])
def test_a_robot_reaches_a_goal_in_a_corner(name):
    """The intersection's goal (7.5, -1.5) lies 0.5 m from the end wall and the side wall. DWA
    without its progress term stopped 1.3 m short for ever (standing still kept its clearance
    term whole); every controller gets there within 40 s."""
    env, params = sgjax.make("intersection", options=policy_options(name), num_agents=1)
    policy = load_policy(name, env)
    obs, state = env.reset(jax.random.key(1), params)
    assert np.allclose([state.route.goal_x[0], state.route.goal_y[0]], [7.5, -1.5])

    def body(carry, key):
        obs, state = carry
        obs, state, *_ = env.step_env(key, state, policy(obs, key, state, params), params)
        return (obs, state), state.robots.succeeded[0]

    _, arrived = jax.jit(lambda c: jax.lax.scan(body, c, jax.random.split(jax.random.key(2),
                                                                           400)))((obs, state))
    assert bool(np.asarray(arrived).any()), name


def test_tracking_turns_in_place_for_a_velocity_behind_and_drives_straight_ahead():
    _, params = sgjax.make("open", num_agents=2, action_mode="continuous")
    rp = params.robots
    actions = track_velocity(jnp.asarray([1.0, -1.0]), jnp.asarray([0.0, 0.0]), jnp.zeros(2),
                             jnp.zeros(2), rp, 2.0, 2)
    assert actions[0, 0] == pytest.approx(1.0 / float(rp.max_speed[0]))  # straight ahead
    assert actions[0, 1] == pytest.approx(0.0)
    assert actions[1, 0] == pytest.approx(0.0)  # behind: no forward speed, full turn
    assert abs(float(actions[1, 1])) == pytest.approx(1.0)


def test_orca_is_a_baseline_of_sgjax_evaluate(capsys):
    for name in ("orca", "dwa", "social_force"):
        assert policy_options(name) == MakeOptions.from_keywords(action_mode="continuous")
    env, _ = sgjax.make("open", num_agents=2)
    with pytest.raises(ValueError, match="needs action_mode 'continuous'"):
        load_policy("orca", env)
    from sgjax.command import main

    main(["evaluate", "--scenario", "open", "--policy", "orca", "--num-agents", "2",
          "--episodes", "2"])
    assert "orca" in capsys.readouterr().out
