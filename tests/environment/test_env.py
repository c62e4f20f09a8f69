"""The environment's API contract: shapes, spaces, determinism, jit/vmap equivalence, retracing,
auto-reset and episode ends, and clear errors for bad input."""

import os

import chex
import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jaxprs import equations, traced_in

import sgjax
from sgjax.environment.env import OBS_SIZE, SETTLE_TOLERANCE
from sgjax.evaluation.runner import with_zone_books


def go_actions(env, batch=None):
    shape = (env.max_agents,) if batch is None else (batch, env.max_agents)
    return jnp.zeros(shape, jnp.int32)


def rollout(env, params, key, steps, actions_fn):
    """Python-loop rollout of env.step (eager when called outside jit)."""
    k_reset, key = jax.random.split(key)
    obs, state = env.reset(k_reset, params)
    out = []
    for t in range(steps):
        key, k_act, k_step = jax.random.split(key, 3)
        obs, state, reward, term, trunc, _ = env.step(k_step, state, actions_fn(k_act, t), params)
        out.append((obs, reward, term, trunc))
    return state, out


def random_go_stop(env):
    return lambda k, t: (jax.random.uniform(k, (env.max_agents,)) < 0.3).astype(jnp.int32)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", sgjax.registered())
def test_api_shapes_and_spaces(scenario):
    env, params = sgjax.make(scenario, num_agents=3)
    assert env.max_agents == 3
    assert env.action_space(params) == gymnasium.spaces.Discrete(2)
    obs, state = env.reset(jax.random.key(0), params)
    assert obs.shape == (3, OBS_SIZE) and obs.dtype == jnp.float32
    assert env.observation_space(params).contains(np.asarray(obs[0]))
    assert state.robots.position.shape == (3, 2)
    assert state.robots.heading.shape == (3,)
    assert state.robots.velocity.shape == (3, 2)
    assert state.robots.active.dtype == jnp.bool_ and bool(state.robots.active.all())
    assert params.robots.radius.shape == (3,)
    obs, state, reward, term, trunc, info = env.step(  # its compiled entry point
        jax.random.key(1), state, go_actions(env), params)
    assert obs.shape == (3, OBS_SIZE)
    for arr in (reward, term, trunc):
        assert arr.shape == (3,)
    assert term.dtype == jnp.bool_ and trunc.dtype == jnp.bool_
    assert {"final_observation", "final_robots", "episode_done"} <= set(info)
    chex.assert_tree_all_finite((obs, reward))


def test_continuous_action_space_shapes():
    env, params = sgjax.make("open", num_agents=2, action_mode="continuous")
    assert env.action_space(params).shape == (2,)
    env3, params3 = sgjax.make("open", num_agents=2, action_mode="continuous",
                               robots=["cobot", "socialgym"])
    assert env3.action_space(params3).shape == (3,)


def test_determinism_same_key_same_result():
    env, params = sgjax.make("doorway", num_agents=4)
    step = jax.jit(env.step)

    def run(key):
        obs, state = env.reset(key, params)
        for t in range(30):
            key, k = jax.random.split(key)
            obs, state, *_ = step(k, state, (jnp.arange(4) == t % 4).astype(jnp.int32), params)
        return obs, state

    a, b = run(jax.random.key(7)), run(jax.random.key(7))
    chex.assert_trees_all_equal(a, b)
    c = run(jax.random.key(8))
    assert not np.array_equal(a[0], c[0])


@pytest.mark.slow
def test_jit_equals_eager():
    """``env.reset`` and ``env.step`` op by op (``disable_jit``) and as the compiled programs
    they call outside it (the ones test_api_shapes_and_spaces[hallway] compiled already)."""
    env, params = sgjax.make("hallway", num_agents=3)
    actions = random_go_stop(env)
    with jax.disable_jit():
        eager_state, eager = rollout(env, params, jax.random.key(3), 8, actions)
    jit_state, jitted = rollout(env, params, jax.random.key(3), 8, actions)
    chex.assert_trees_all_close(eager, jitted, rtol=1e-5, atol=1e-5)
    chex.assert_trees_all_close(eager_state, jit_state, rtol=1e-5, atol=1e-5)


@pytest.mark.slow
def test_vmap_equals_loop():
    env, params = sgjax.make("intersection", num_agents=4, action_mode="continuous")
    keys = jax.random.split(jax.random.key(4), 5)
    obs, states = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    actions = jax.random.uniform(jax.random.key(5), (5, 4, 2), minval=-1, maxval=1)
    step_keys = jax.random.split(jax.random.key(6), 5)
    batched = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))(step_keys, states, actions,
                                                                    params)
    step = jax.jit(env.step)
    for i in range(5):
        state_i = jax.tree.map(lambda leaf, i=i: leaf[i], states)
        single = step(step_keys[i], state_i, actions[i], params)
        chex.assert_trees_all_close(jax.tree.map(lambda leaf, i=i: leaf[i], batched[:5]),
                                    single[:5], rtol=1e-5, atol=1e-6)


def _batch_rollout(env, params, num_envs, steps, step_fn, key):
    """``steps`` steps of ``num_envs`` environments with random actions; every step's returns."""
    _, states = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(key, num_envs), params)
    # Staggered clocks: some episodes end alone, others in bursts (time limit 2 s = 20 steps).
    clocks = jnp.maximum(jnp.arange(num_envs) - 3, 0) * 3  # 0 0 0 0 3 6 9 ...
    states = states.replace(time=clocks.astype(states.time.dtype))
    continuous = env.config.action_mode == "continuous"
    outputs = []
    for t in range(steps):
        k_act, k_step = jax.random.split(jax.random.fold_in(key, t))
        shape = (num_envs, env.max_agents) + ((2,) if continuous else ())
        actions = (jax.random.uniform(k_act, shape, minval=-1, maxval=1) if continuous
                   else (jax.random.uniform(k_act, shape) < 0.3).astype(jnp.int32))
        out = step_fn(jax.random.split(k_step, num_envs), states, actions, params)
        states = out[1]
        outputs.append(out)
    return outputs


@pytest.mark.slow
@pytest.mark.parametrize("action_mode", ["go_stop", "continuous"])
def test_step_batch_is_vmap_of_step_bitwise(action_mode):
    """``env.step_batch`` resets only the ended environments, a few per chunk, and returns
    exactly what ``vmap(step)`` (which resets every environment, keeping the ended ones')
    returns: observations, states, rewards, flags and infos, over 45 steps in which episodes
    end alone and in bursts larger than the chunk."""
    env, params = sgjax.make("doorway", num_agents=3, action_mode=action_mode, time_limit=2.0)
    vstep = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))
    bstep = jax.jit(lambda k, s, a, p: env.step_batch(k, s, a, p, reset_chunk=2))
    key = jax.random.key(11)
    expected = _batch_rollout(env, params, 9, 45, vstep, key)
    got = _batch_rollout(env, params, 9, 45, bstep, key)
    ended = [int(out[5]["episode_done"].sum()) for out in expected]
    assert sum(ended) >= 18 and max(ended) > 2 and 1 in ended, ended  # alone and in bursts
    # Bitwise under the default compile; the suite's fast-compile flags (tests/conftest.py)
    # let XLA round the two programs' floats differently, by about 1e-6 m.
    exact = os.environ.get("SGJAX_TEST_FULL_OPTIMIZATION") == "1"
    for t, (a, b) in enumerate(zip(expected, got, strict=True)):
        assert jax.tree.structure(a) == jax.tree.structure(b)
        for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
            x, y = np.asarray(x), np.asarray(y)
            if exact or not np.issubdtype(x.dtype, np.floating):
                np.testing.assert_array_equal(x, y, err_msg=f"step {t}")
            else:
                np.testing.assert_allclose(x, y, rtol=1e-5, atol=2e-5, err_msg=f"step {t}")


def test_step_batch_under_an_outer_vmap_and_its_errors():
    """Lanes (an outer ``vmap``, as the trainer's seeds) with different numbers of ended
    episodes step as each lane alone; a bad chunk and a bad action are errors."""
    env, params = sgjax.make("doorway", num_agents=2, time_limit=1.0)
    keys = jax.random.split(jax.random.key(3), 6)
    _, states = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    # Lane 0: every episode ends at the next step; lane 1: none does.
    clocks = jnp.stack([jnp.full(3, 9), jnp.zeros(3)]).astype(states.time.dtype)
    lanes = jax.tree.map(lambda leaf: leaf.reshape(2, 3, *leaf.shape[1:]), states)
    lanes = lanes.replace(time=clocks)
    actions = jnp.zeros((2, 3, env.max_agents), jnp.int32)
    step_keys = jax.random.split(jax.random.key(4), 6).reshape(2, 3)
    both = jax.jit(jax.vmap(lambda k, s, a: env.step_batch(k, s, a, params, 1)))(
        step_keys, lanes, actions)
    vstep = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))
    for lane in range(2):
        alone = vstep(step_keys[lane], jax.tree.map(lambda leaf, i=lane: leaf[i], lanes),
                      actions[lane], params)
        chex.assert_trees_all_close(jax.tree.map(lambda leaf, i=lane: leaf[i], both), alone,
                                    rtol=1e-5, atol=2e-5)
    assert both[5]["episode_done"].tolist() == [[True] * 3, [False] * 3]
    with pytest.raises(ValueError, match="reset_chunk must be a positive int, got 0"):
        env.step_batch(keys, states, jnp.zeros((6, 2), jnp.int32), params, reset_chunk=0)
    with pytest.raises(ValueError, match="robot slot 1 of batch index 2"):
        env.step_batch(keys, states, jnp.zeros((6, 2), jnp.int32).at[2, 1].set(5), params)


def test_no_retrace_when_robot_count_changes():
    env, params = sgjax.make("doorway", num_agents=3, max_agents=6)
    traces = {"reset": 0, "step": 0}

    def reset(key, p):
        traces["reset"] += 1
        return env.reset(key, p)

    def step(key, state, actions, p):
        traces["step"] += 1
        return env.step(key, state, actions, p)

    reset_j, step_j = jax.jit(reset), jax.jit(step)
    for n in (3, 6, 1, 4):
        p = params.replace(num_agents=jnp.asarray(n, jnp.int32))
        _, state = reset_j(jax.random.key(n), p)
        assert int(state.robots.present.sum()) == n
        step_j(jax.random.key(0), state, go_actions(env), p)
    assert traces == {"reset": 1, "step": 1}


@pytest.mark.slow
def test_inactive_slots_are_absorbing_and_masked():
    env, params = sgjax.make("open", num_agents=2, max_agents=5, action_mode="continuous")
    obs, state = env.reset(jax.random.key(0), params)
    assert state.robots.present.tolist() == [True, True, False, False, False]
    assert float(jnp.abs(obs[2:]).sum()) == 0.0
    actions = jnp.ones((5, 2))
    obs2, state2, reward, term, trunc, _ = env.step_env(jax.random.key(1), state, actions, params)
    np.testing.assert_array_equal(state2.robots.position[2:], state.robots.position[2:])
    assert float(jnp.abs(reward[2:]).sum()) == 0.0
    assert not bool(term[2:].any() | trunc[2:].any())


@pytest.mark.slow
@pytest.mark.parametrize("arrived", ["park", "settle"])
def test_success_is_terminal_and_absorbing(arrived):
    """Success is rewarded once and terminal for good; the robot is frozen where it arrived
    (``park``) or once it has parked on its goal point (``settle``)."""
    env, params = sgjax.make("open", num_agents=1, arrived=arrived)
    obs, state = env.reset(jax.random.key(2), params)
    step = jax.jit(env.step_env)
    arrived_at, frozen = None, None
    for t in range(400):
        obs, state, reward, term, trunc, info = step(jax.random.key(t), state, go_actions(env),
                                                     params)
        if arrived_at is None and bool(term[0]):
            arrived_at = t
            assert float(reward[0]) > 50.0  # success reward once
        elif arrived_at is not None:
            assert bool(term[0]) and float(reward[0]) == 0.0
        if frozen is not None:
            np.testing.assert_array_equal(state.robots.position, frozen)
        elif bool(state.robots.parked[0]):
            frozen = state.robots.position
    assert arrived_at is not None and frozen is not None
    goal = np.array([float(state.route.goal_x[0]), float(state.route.goal_y[0])])
    to_goal = float(np.hypot(*(np.asarray(frozen[0]) - goal)))
    assert to_goal < (SETTLE_TOLERANCE if arrived == "settle" else params.goal_tolerance)


def test_auto_reset_keeps_final_observation():
    env, params = sgjax.make("open", num_agents=1)
    _, state = env.reset(jax.random.key(3), params)
    step = jax.jit(env.step)
    for t in range(400):
        obs, new_state, reward, term, trunc, info = step(jax.random.key(t), state,
                                                         go_actions(env), params)
        if bool(info["episode_done"]):
            assert bool(term[0])
            assert int(new_state.time) == 0 and not bool(new_state.robots.succeeded.any())
            assert float(info["final_observation"][0, -1]) < float(params.goal_tolerance)
            assert bool(info["final_robots"].succeeded[0])
            break
        state = new_state
    else:
        pytest.fail("episode never ended")


@pytest.mark.slow
def test_time_limit_truncates():
    env, params = sgjax.make("doorway", num_agents=2, time_limit=1.0)
    _, state = env.reset(jax.random.key(0), params)
    stop = jnp.ones(2, jnp.int32)
    step = jax.jit(env.step)
    for t in range(10):
        _, state_next, _, term, trunc, info = step(jax.random.key(t), state, stop, params)
        if t < 9:
            assert not bool(trunc.any()) and not bool(info["episode_done"])
            state = state_next
    assert bool(trunc.all()) and not bool(term.any()) and bool(info["episode_done"])


def test_collision_onsets_counted_once_and_bodies_never_overlap():
    env, params = sgjax.make("open", num_agents=2, action_mode="continuous")
    start = jnp.array([12, 36])  # (-6, 0) and (6, 0), facing each other
    _, state = env.reset_to(start, start[::-1], jnp.array([True, True]), params)
    forward = jnp.array([[1.0, 0.0], [1.0, 0.0]])
    step = jax.jit(env.step_env)
    touching_diameter = 2 * float(params.robots.radius[0])
    for t in range(120):
        _, state, _, _, _, info = step(jax.random.key(t), state, forward, params)
        gap = float(jnp.linalg.norm(state.robots.position[0] - state.robots.position[1]))
        assert gap >= touching_diameter - 1e-4, (t, gap)  # pushed apart after every step
    # Driven into each other they touch once, press, and (frictionless discs) slide around
    # each other: one onset each, however long the contact lasts.
    np.testing.assert_array_equal(state.collisions.robot, [1, 1])


def test_bad_input_errors():
    with pytest.raises(KeyError, match="registered scenarios are: doorway"):
        sgjax.make("corridor")
    with pytest.raises(TypeError, match=r"unknown option 'num_agent' \(did you mean "
                       r"'num_agents'\?\); valid options are: num_agents"):
        sgjax.make("doorway", num_agent=3)
    with pytest.raises(KeyError, match=r"'doorwya' \(did you mean 'doorway'\?\)"):
        sgjax.make("doorwya")
    with pytest.raises(ValueError, match=r"action_mode .* got 'continous' \(did you mean "
                       r"'continuous'\?\)"):
        sgjax.make("doorway", action_mode="continous")
    with pytest.raises(ValueError, match="human_radius must be a positive number"):
        sgjax.make("doorway", human_radius=-1.0)
    with pytest.raises(ValueError, match="give observations= or observation_preset=, not both"):
        sgjax.make("doorway", observations="default", observation_preset="navigation")
    with pytest.raises(ValueError, match="num_agents"):
        sgjax.make("doorway", num_agents=0)
    with pytest.raises(ValueError, match="must not exceed max_agents"):
        sgjax.make("doorway", num_agents=5, max_agents=3)
    with pytest.raises(ValueError, match="action_mode"):
        sgjax.make("doorway", action_mode="velocity")
    with pytest.raises(ValueError, match="unknown robot preset 'pr2'"):
        sgjax.make("doorway", robots="pr2")
    with pytest.raises(ValueError, match="radius must be a positive number"):
        sgjax.make("doorway", robots=sgjax.RobotPreset("diff_drive", -0.1, 1, 0, 1, 1, 1, 1))
    with pytest.raises(ValueError, match="max_speed must be a positive number"):
        sgjax.make("doorway", robots=sgjax.RobotPreset("diff_drive", 0.2, 0, 0, 1, 1, 1, 1))
    with pytest.raises(ValueError, match="substeps=1 is too few"):
        sgjax.make("doorway", dt=0.5, substeps=1)
    with pytest.raises(ValueError, match="cannot place max_agents=30"):
        sgjax.make("doorway", num_agents=30)
    env, params = sgjax.make("doorway", num_agents=2)
    _, state = env.reset(jax.random.key(0), params)
    with pytest.raises(ValueError, match=r"actions: expected shape \(2,\)"):
        env.step(jax.random.key(0), state, jnp.zeros(3, jnp.int32), params)
    with pytest.raises(ValueError, match="expected integers"):
        env.step(jax.random.key(0), state, jnp.zeros(2), params)
    cenv, cparams = sgjax.make("doorway", num_agents=2, action_mode="continuous")
    _, cstate = cenv.reset(jax.random.key(0), cparams)
    with pytest.raises(ValueError, match=r"expected shape \(2, 2\)"):
        cenv.step(jax.random.key(0), cstate, jnp.zeros((2, 3)), cparams)


@pytest.mark.slow
def test_scenario_sampling_constraints():
    env, params = sgjax.make("intersection", num_agents=10)
    keys = jax.random.split(jax.random.key(9), 256)
    _, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, params)
    assert bool(states.robots.present.all())
    starts, goals = np.asarray(states.route.start), np.asarray(states.route.goal)
    for s, g in zip(starts, goals, strict=True):
        assert len(set(s)) == 10 and len(set(g)) == 10
    pos = np.asarray(states.robots.position)
    gaps = np.linalg.norm(pos[:, :, None] - pos[:, None, :], axis=-1) + np.eye(10) * 99
    assert gaps.min() >= 2 * float(params.robots.radius[0])
    # Every start and goal of the map gets used across draws (the sampler explores them all).
    assert len(np.unique(starts)) == 14 and len(np.unique(goals)) == 14


def test_params_checked_on_reset():
    env, params = sgjax.make("doorway", num_agents=2, max_agents=3)
    with pytest.raises(ValueError, match=r"params.num_agents must be in \[0, max_agents=3\]"):
        env.reset(jax.random.key(0), params.replace(num_agents=jnp.int32(4)))
    with pytest.raises(ValueError, match="params.dt must be positive"):
        env.reset(jax.random.key(0), params.replace(dt=jnp.float32(0.0)))


def test_reset_to_validates_shapes():
    env, params = sgjax.make("doorway", num_agents=2)
    with pytest.raises(ValueError, match=r"start must have shape \(2,\)"):
        env.reset_to(jnp.array([0]), jnp.array([22, 23]), jnp.array([True, True]), params)


def test_make_options_grouped_and_flat_agree():
    from sgjax.environment.options import HumanOptions, MakeOptions, PhysicsOptions, RobotOptions

    options = MakeOptions(robots=RobotOptions(num_agents=2, max_agents=3),
                          humans=HumanOptions(num_humans=1, human_model="helbing"),
                          physics=PhysicsOptions(dt=0.05, time_limit=10.0))
    flat = options.keywords(changed_only=True)
    assert flat == {"num_agents": 2, "max_agents": 3, "num_humans": 1,
                    "human_model": "helbing", "dt": 0.05, "time_limit": 10.0}
    assert MakeOptions.from_keywords(**flat) == options
    env, params = sgjax.make("doorway", options=options, num_agents=3)
    assert env.max_agents == 3 and int(params.num_agents) == 3
    assert int(params.max_steps) == 200 and env.config.humans.force_model == "helbing"
    assert env.config.layout.max_humans == 1 and env.config.layout.max_agents == 3


def test_min_agents_draws_each_episodes_robot_count():
    """``min_agents`` draws every episode's count from [min_agents, num_agents]; without it
    every episode has ``num_agents`` (one compiled reset for both)."""
    env, params = sgjax.make("doorway", num_agents=5, min_agents=2)
    reset = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))
    _, state = reset(jax.random.split(jax.random.key(0), 400), params)
    counts = np.asarray(state.robots.present.sum(axis=1))
    assert set(counts.tolist()) == {2, 3, 4, 5}
    _, state = reset(jax.random.split(jax.random.key(0), 8), params.replace(
        min_agents=jnp.asarray(0, jnp.int32)))
    assert np.all(np.asarray(state.robots.present.sum(axis=1)) == 5)
    with pytest.raises(ValueError, match="min_agents"):
        sgjax.make("doorway", num_agents=3, min_agents=4)


@pytest.mark.parametrize("action_mode", ["go_stop", "continuous"])
def test_invalid_actions_are_an_error_outside_jit_and_neutral_flagged_inside(action_mode):
    """NaN in one robot's continuous action (or GO/STOP 7) names the slot when called eagerly;
    jitted, that robot gets the neutral action (zero command / STOP), the flag says so, and no
    NaN reaches any robot (it did before: every position, observation and reward went NaN)."""
    env, params = sgjax.make("doorway", num_agents=3, max_agents=3, action_mode=action_mode)
    _, state = env.reset(jax.random.key(0), params)
    if action_mode == "continuous":
        good = jnp.full((3, 2), 0.5)
        bad = good.at[1, 0].set(jnp.nan)
        neutral = good.at[1].set(0.0)
        message = r"robot slot 1 has action \[nan, 0.5\]; continuous actions must be finite"
    else:
        good = jnp.zeros(3, jnp.int32)
        bad = good.at[1].set(7)
        neutral = good.at[1].set(1)
        message = r"robot slot 1 has action 7; GO/STOP actions are 0 \(GO\) or 1 \(STOP\)"
    with pytest.raises(ValueError, match=message):
        env.step(jax.random.key(1), state, bad, params)
    with pytest.raises(ValueError, match=message):
        env.step_env(jax.random.key(1), state, bad, params)
    step = jax.jit(env.step_env)
    s_bad, s_neutral = state, state
    for t in range(5):
        obs, s_bad, reward, _, _, info = step(jax.random.key(t), s_bad, bad, params)
        ref_obs, s_neutral, ref_reward, _, _, ref_info = step(jax.random.key(t), s_neutral,
                                                              neutral, params)
        assert info["invalid_action"].tolist() == [False, True, False]
        assert not ref_info["invalid_action"].any()
        assert bool(jnp.all(jnp.isfinite(obs))) and bool(jnp.all(jnp.isfinite(reward)))
        np.testing.assert_array_equal(np.asarray(obs), np.asarray(ref_obs))
        np.testing.assert_array_equal(np.asarray(reward), np.asarray(ref_reward))


def test_zone_books_are_traced_only_where_something_reads_them():
    """The doorway has a conflict zone; with terms that read no zone (the default) the reset
    and the step trace none of the zone bookkeeping (training programs compile none of it) and
    carry ``[R, 0]`` books of the dtypes the tracked ones have; with the zone terms, or
    ``track_zones`` (the evaluation runner's), it is traced and the books are ``[R, 1]``."""
    key = jax.random.key(0)
    books = {}
    for name, options in (("none", {}), ("terms", {"observations": "enforced_order",
                                                    "rewards": "enforced_order"}),
                          ("tracked", {})):
        env, params = sgjax.make("doorway", num_agents=2, **options)
        if name == "tracked":
            env = with_zone_books(env)
        actions = jnp.zeros(env.max_agents, jnp.int32)

        def reset_and_step(k, p, env=env, actions=actions):
            _, state = env.reset(k, p)
            return env.step(k, state, actions, p)[1].zones

        jaxpr = jax.make_jaxpr(reset_and_step)(key, params).jaxpr
        where = filter(None, (traced_in(eqn) for eqn in equations(jaxpr)))
        used = {function for file, function in where if file.endswith("zone_books.py")}
        if name == "none":
            assert used <= {"no_zones"}, used
        else:
            assert {"start_zones", "update_zones"} <= used, (name, used)
        books[name] = jax.eval_shape(reset_and_step, key, params)
    for name in ("terms", "tracked"):
        for none, kept in zip(jax.tree.leaves(books["none"]), jax.tree.leaves(books[name]),
                              strict=True):
            assert none.shape == (2, 0) and kept.shape == (2, 1), (name, kept.shape)
            assert (none.dtype, none.weak_type) == (kept.dtype, kept.weak_type), name
