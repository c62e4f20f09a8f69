"""Reward terms on hand-built transitions with answers worked out by hand; the Rewarder's sum
and per-term info; weight schedules."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scenes import make_room, place

from sgjax.kernels import zone_books as zn
from sgjax.rewards import REWARDS, Rewarder, constant, linear, parse_schedule
from sgjax.rewards.schedules import Schedule
from sgjax.terms.base import ConfigError
from sgjax.terms.contract import TermInput


def step_inputs(env, params, prev, state, actions=None):
    """The one term input for the step from ``prev`` to ``state`` (GO for every robot)."""
    actions = jnp.zeros(env.max_agents, jnp.int32) if actions is None else actions
    return TermInput(prev=prev, state=state, actions=actions, params=params,
                     key=jax.random.key(0), layout=env.config.layout)


def value(spec, env, params, prev, state, actions=None):
    """Raw (unweighted) value of one reward term, ``{name: options}`` or a name."""
    name, options = (spec, {}) if isinstance(spec, str) else next(iter(spec.items()))
    term = REWARDS.build("test", name, options)
    return np.asarray(term(step_inputs(env, params, prev, state, actions)))


@pytest.fixture(scope="module")
def room():
    return make_room(num_agents=2, max_agents=2, num_humans=2)


def moved(state, **robot_fields):
    return state.replace(robots=state.robots.replace(**robot_fields))


def test_existence_and_success_once(room):
    env, params = room
    prev = place(env, params, [3.0, -3.0], [0.0, 0.0])
    arrived = moved(prev, succeeded=jnp.asarray([True, False]))
    np.testing.assert_array_equal(value("existence", env, params, prev, arrived), [0, -1])
    np.testing.assert_array_equal(value("success", env, params, prev, arrived), [1, 0])
    # The step after: success is not paid again.
    np.testing.assert_array_equal(value("success", env, params, arrived, arrived), [0, 0])


def test_collision_onsets_and_per_step(room):
    env, params = room
    prev = place(env, params, [3.0, -3.0], [0.0, 0.0])
    touching = prev.replace(touching_wall=jnp.asarray([True, False]),
                            touching_human=jnp.asarray([False, True]))
    np.testing.assert_array_equal(value("collision", env, params, prev, touching), [-1, -1])
    np.testing.assert_array_equal(value({"collision": {"humans": False}}, env, params, prev,
                                        touching), [-1, 0])
    # Still touching the next step: no new onset, but per_step keeps paying.
    np.testing.assert_array_equal(value("collision", env, params, touching, touching), [0, 0])
    np.testing.assert_array_equal(value({"collision": {"per_step": True}}, env, params,
                                        touching, touching), [-1, -1])


def test_progress_clip_and_goal_distance(room):
    env, params = room
    # Goal (node 1) at (4, 0): from x = -1 (5 m away) to x = -0.5 (4.5 m away).
    prev = place(env, params, [-1.0, 2.0], [0.0, 0.0], goals=[1, 1])
    after = moved(prev, x=jnp.asarray([-0.5, 1.0]))
    np.testing.assert_allclose(value("progress", env, params, prev, after), [0.5, -1.0],
                               atol=1e-5)
    np.testing.assert_allclose(value({"progress": {"clip": [0.0, 0.2]}}, env, params, prev,
                                     after), [0.2, 0.0], atol=1e-6)
    np.testing.assert_allclose(value("goal_distance", env, params, prev, after), [-4.5, -3],
                               atol=1e-5)
    np.testing.assert_allclose(value({"goal_distance": {"form": "inverse"}}, env, params, prev,
                                     after), [1 / 4.5, 1 / 3], atol=1e-6)
    along = after.replace(progress=jnp.asarray([0.7, 0.0]))
    np.testing.assert_allclose(value({"progress": {"along_route": True}}, env, params, prev,
                                     along), [0.7, 0.0], atol=1e-6)


def test_velocity_change_and_preferred_velocity(room):
    env, params = room
    prev = place(env, params, [0.0, 2.0], [0.0, 0.0], headings=[0.0, 0.0], speeds=[1.0, 1.0])
    turned = moved(prev, kin=prev.robots.kin.replace(heading=jnp.asarray([math.pi / 2, 0.0])))
    # (1, 0) -> (0, 1): |dv|^2 = 2. (SocialGym's (sum of components)^2 would say 0.)
    np.testing.assert_allclose(value("velocity_change", env, params, prev, turned), [-2, 0],
                               atol=1e-5)
    np.testing.assert_allclose(value({"preferred_velocity": {"speed": 1.5}}, env, params, prev,
                                     turned), [-0.25, -0.25], atol=1e-5)


def test_proximity_and_personal_space(room):
    env, params = room
    r, rh = float(params.robots.radius[0]), float(params.humans.radius)
    # Robots 0.1 m apart (body to body); a pedestrian 0.225 m beyond robot 1's body.
    xs = [0.0, 2 * r + 0.1]
    state = place(env, params, xs, [0.0, 0.0],
                  humans=[(xs[1] + r + rh + 0.225, 0.0, 0.0, 0.0)])
    np.testing.assert_allclose(value("proximity", env, params, state, state),
                               [-0.05, -0.05], atol=1e-5)
    np.testing.assert_allclose(value({"proximity": {"robots": False}}, env, params, state,
                                     state), [0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(value("personal_space", env, params, state, state), [0, -0.5],
                               atol=1e-5)


@pytest.mark.parametrize("other, heading, speeds, term, expected", [
    # Oncoming, ahead on the right: wrong side; on the left: fine.
    ((2.0, -1.0), math.pi, (1.0, 1.0), "social_norm_pass", -1),
    ((2.0, 1.0), math.pi, (1.0, 1.0), "social_norm_pass", 0),
    # Same way and slower, ahead on the left: overtaking it would be on its right.
    ((1.0, 0.5), 0.0, (1.0, 0.2), "social_norm_overtake", -1),
    ((1.0, -0.5), 0.0, (1.0, 0.2), "social_norm_overtake", 0),
    ((1.0, 0.5), 0.0, (0.2, 1.0), "social_norm_overtake", 0),  # not faster: no overtaking
    # Crossing from the left toward the right, within 2 m.
    ((1.0, 1.0), -math.pi / 2, (1.0, 1.0), "social_norm_cross", -1),
    ((1.0, -1.0), math.pi / 2, (1.0, 1.0), "social_norm_cross", 0),
])
def test_social_norms(other, heading, speeds, term, expected):
    env, params = make_room(num_agents=2, max_agents=2)
    # The robot at (-4, 0)... placed at the origin facing +x, 4 m from its goal (node 1).
    prev = place(env, params, [0.0, other[0]], [0.0, other[1]], headings=[0.0, heading],
                 speeds=list(speeds), goals=[1, 0])
    got = value(term, env, params, prev, prev)
    assert got[0] == expected
    # Within 3 m of the goal the norms are off.
    close = place(env, params, [2.0, 2.0 + other[0]], [0.0, other[1]], headings=[0.0, heading],
                  speeds=list(speeds), goals=[1, 0])
    assert value(term, env, params, close, close)[0] == 0


def zone_scene(env, params, xs, keys, phases, contained, entered_at=(0, 0)):
    state = place(env, params, xs, [0.0] * len(xs), starts=[0] * len(xs), goals=[1] * len(xs))
    zones = zn.ZoneState(
        participant=jnp.ones((2, 1), bool),
        priority_key=jnp.asarray(keys, jnp.float32)[:, None],
        phase=jnp.asarray(phases, jnp.int32)[:, None],
        was_contained=jnp.asarray(contained)[:, None],
        entered_at=jnp.asarray(entered_at, jnp.int32)[:, None],
    )
    return state.replace(zones=zones)


def step_zones(env, params, prev, xs):
    after = moved(prev, x=jnp.asarray(xs, jnp.float32))
    return after.replace(zones=zn.update_zones(prev.zones, after.robots.x, after.robots.y,
                                               params.robots.radius, params.map.zone_rect, 5))


def test_zone_order_enforced_and_any_order():
    env, params = make_room(num_agents=2, max_agents=2)
    enforced = {"zone_order": {}}
    any_order = {"zone_order": {"any_order": True}}
    # Robot 1 is due first (key 0.1) but robot 0 is nearer and enters first.
    prev = zone_scene(env, params, [-1.3, -3.0], [0.9, 0.1], [zn.BEFORE, zn.BEFORE],
                      [False, False])
    entering = step_zones(env, params, prev, [-1.0, -3.0])
    np.testing.assert_array_equal(value(enforced, env, params, prev, entering), [0, 0])
    np.testing.assert_array_equal(value(any_order, env, params, prev, entering), [1, 0])
    # ...then leaves out of turn: -1 under Enforced Order, 0 under Any Order.
    inside = zone_scene(env, params, [0.9, -3.0], [0.9, 0.1], [zn.INSIDE, zn.BEFORE],
                        [True, False])
    out = step_zones(env, params, inside, [1.5, -3.0])
    np.testing.assert_array_equal(value(enforced, env, params, inside, out), [-1, 0])
    np.testing.assert_array_equal(value(any_order, env, params, inside, out), [0, 0])
    np.testing.assert_array_equal(value({"zone_order": {"incorrect_penalty": False}}, env,
                                        params, inside, out), [0, 0])
    # In turn (robot 0 due first): +1 on entry.
    prev = zone_scene(env, params, [-1.3, -3.0], [0.1, 0.9], [zn.BEFORE, zn.BEFORE],
                      [False, False])
    entering = step_zones(env, params, prev, [-1.0, -3.0])
    np.testing.assert_array_equal(value(enforced, env, params, prev, entering), [1, 0])


def test_zone_order_multiple_entry_penalty_and_continuous():
    env, params = make_room(num_agents=2, max_agents=2)
    # Both straddle the left edge on the same step (one above the other is not possible on
    # the line y = 0, so robot 1 comes in from the right edge).
    prev = zone_scene(env, params, [-1.3, 1.3], [0.1, 0.9], [zn.BEFORE, zn.BEFORE],
                      [False, False])
    both = step_zones(env, params, prev, [-1.0, 1.0])
    np.testing.assert_array_equal(value({"zone_order": {"any_order": True}}, env, params, prev,
                                        both), [-1, -1])
    np.testing.assert_array_equal(value({"zone_order": {"any_order": True,
                                                        "multiple_entry_penalty": False}},
                                        env, params, prev, both), [1, 1])
    # Continuous: both in turn outside (+0.1 each); swapped priorities: both out of turn.
    continuous = {"zone_order": {"continuous": True}}
    np.testing.assert_allclose(value(continuous, env, params, prev, prev), [0.1, 0.1],
                               atol=1e-6)
    swapped = zone_scene(env, params, [-1.3, 1.3], [0.9, 0.1], [zn.BEFORE, zn.BEFORE],
                         [False, False])
    np.testing.assert_allclose(value(continuous, env, params, swapped, swapped), [-0.1, -0.1],
                               atol=1e-6)
    # Robot 0 inside and due: +1 (inside); robot 1 waits in turn outside: +0.1.
    inside = zone_scene(env, params, [0.0, 1.3], [0.1, 0.9], [zn.INSIDE, zn.BEFORE],
                        [True, False])
    np.testing.assert_allclose(value(continuous, env, params, inside, inside), [1.0, 0.1],
                               atol=1e-6)


def test_rewarder_sums_weighted_terms_and_reports_each():
    rewarder, weights = Rewarder.parse({"existence": 2.0, "collision": {"weight": 10.0},
                                       "progress": {"weight": 1.0, "clip": [0.0, 1.0]}})
    env, params = make_room(num_agents=2, max_agents=2, rewards={
        "existence": 2.0, "collision": {"weight": 10.0},
        "progress": {"weight": 1.0, "clip": [0.0, 1.0]}})
    assert env.config.rewarder == rewarder
    prev = place(env, params, [-1.0, 2.0], [0.0, 0.0])
    after = moved(prev, x=jnp.asarray([-0.5, 2.0])).replace(
        touching_robot=jnp.asarray([False, True]))
    total, parts = env.config.rewarder(step_inputs(env, params, prev, after))
    np.testing.assert_allclose(parts["existence"], [-2, -2])
    np.testing.assert_allclose(parts["collision"], [0, -10])
    np.testing.assert_allclose(parts["progress"], [0.5, 0], atol=1e-5)
    np.testing.assert_allclose(total, [-1.5, -12], atol=1e-5)
    # Robots that were not active get nothing.
    gone = moved(prev, succeeded=jnp.asarray([False, True]))
    total, parts = env.config.rewarder(step_inputs(env, params, gone, after))
    assert float(total[1]) == 0 and all(float(v[1]) == 0 for v in parts.values())


def test_env_step_reports_reward_terms_and_scheduled_weights():
    spec = {"existence": {"schedule": "linear", "start": 0.0, "end": 4.0, "steps": 4},
            "progress": 1.0}
    env, params = make_room(num_agents=2, rewards=spec)
    state = place(env, params, [-4.0, 4.0], [0.0, 0.0], starts=[0, 1], goals=[1, 0])
    actions = jnp.ones(2, jnp.int32)  # STOP: no progress
    import jax
    for t in range(4):
        state = state.replace(total_steps=jnp.asarray(t, jnp.int32))
        _, _, reward, _, _, info = env.step(jax.random.key(t), state, actions, params)
        np.testing.assert_allclose(info["reward_terms"]["existence"], [-t, -t])
        np.testing.assert_allclose(reward, [-t, -t], atol=1e-6)


def test_schedules():
    assert float(constant(3.0)(12345)) == 3.0
    # A one-point schedule skips the search: bit for bit what either rule gives, at any step,
    # in the shape of the steps asked for.
    steps = jnp.asarray([-1e9, 0.0, 4.999, 5.0, 5.001, 2.0**31], jnp.float32)
    for rule in ("linear", "step"):
        for value in (-1.5, 0.0, 1e-8):
            one = Schedule(jnp.asarray([5.0]), jnp.asarray([value], jnp.float32), rule)
            assert one(steps).shape == steps.shape and one(7).shape == ()
            np.testing.assert_array_equal(one(steps), jnp.interp(steps, one.steps, one.values))
    ramp = linear(0.0, 10.0, steps=100, begin=50)
    np.testing.assert_allclose([float(ramp(t)) for t in (0, 50, 100, 150, 1000)],
                               [0, 0, 5, 10, 10])
    held = parse_schedule("w", {"schedule": "piecewise", "interpolation": "step",
                                "points": [[0, 1.0], [10, 2.0], [20, 5.0]]})
    np.testing.assert_allclose([float(held(t)) for t in (0, 9, 10, 19, 25)], [1, 1, 2, 2, 5])
    smooth = parse_schedule("w", {"schedule": "piecewise", "points": [[0, 0.0], [10, 1.0]]})
    assert float(smooth(5)) == pytest.approx(0.5)
    with pytest.raises(ConfigError, match="steps must increase"):
        parse_schedule("w", {"schedule": "piecewise", "points": [[10, 1.0], [5, 2.0]]})
    with pytest.raises(ConfigError, match="schedule: expected one of"):
        parse_schedule("w", {"schedule": "cosine"})
    with pytest.raises(ConfigError, match="needs 'end'"):
        parse_schedule("w", {"schedule": "linear", "start": 0, "steps": 5})


def test_reward_config_errors():
    with pytest.raises(ConfigError, match="unknown reward term 'sucess'.*did you mean 'success'"):
        Rewarder.parse({"sucess": 100})
    with pytest.raises(ConfigError, match="valid reward terms are: .*zone_order"):
        Rewarder.parse({"bogus": 1})
    with pytest.raises(ConfigError, match="collision: unknown option 'per_stp'"):
        Rewarder.parse({"collision": {"per_stp": True}})
    with pytest.raises(ConfigError, match="expected a number"):
        Rewarder.parse({"success": "lots"})
    with pytest.raises(ConfigError, match="clip must be"):
        Rewarder.parse({"progress": {"clip": [1.0, 0.0]}})
    assert isinstance(Rewarder.parse({})[0], Rewarder)


def test_schedule_clock_runs_across_auto_resets_and_pettingzoo_resets():
    import jax

    from sgjax.adapters.pettingzoo import parallel_env
    env, params = make_room(num_agents=2, time_limit=0.5)  # 5-step episodes
    _, state = env.reset(jax.random.key(0), params)
    step = jax.jit(env.step)
    ends = 0
    for t in range(12):
        _, state, _, _, _, info = step(jax.random.key(t), state, jnp.ones(2, jnp.int32), params)
        ends += int(info["episode_done"])
        assert int(state.total_steps) == t + 1
    assert ends == 2
    pz = parallel_env("doorway", num_agents=2, time_limit=0.3)
    pz.reset(seed=0)
    for _ in range(3):
        infos = pz.step({a: 0 for a in pz.agents})[4]
    assert set(infos["robot_0"]["reward_terms"]) == {"progress", "success", "collision"}
    pz.reset()
    assert int(pz._state.total_steps) == 3
