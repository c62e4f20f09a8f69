"""Every metric on hand-built trajectories with known values, and the confidence intervals."""

import dataclasses
import math
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scenes import make_room, place

from sgjax.environment.env import SocialNavEnv
from sgjax.evaluation import metrics
from sgjax.evaluation.evaluate import run_episodes
from sgjax.evaluation.metrics import catalogue
from sgjax.evaluation.statistics import (
    interquartile_mean,
    paired_difference,
    seed_aggregate,
    summarize,
    t_interval,
    wilson_interval,
)
from sgjax.kernels.zone_books import update_zones
from sgjax.types import CollisionCounts

DT = 0.1


def room(num_agents=2, **kw):
    env, params = make_room(num_agents=num_agents, dt=DT, **kw)
    return env, params


def play(env, params, frames, arrived=None, done_at=None):
    """Feed ``frames`` (states, step 0 first) through the accumulators; ``arrived`` maps a step
    to the robots arriving on it. Returns ``finalize``'s ``(robot, episode)`` as numpy."""
    m = metrics.start(env.max_agents)
    prev = frames[0]
    for t in range(1, len(frames)):
        now = np.zeros(env.max_agents, bool)
        for i in (arrived or {}).get(t, ()):
            now[i] = True
        state = frames[t].replace(time=jnp.int32(t))
        state = state.replace(robots=state.robots.replace(
            succeeded=prev.robots.succeeded | jnp.asarray(now)))
        info = {"was_active": prev.robots.active, "arrived": jnp.asarray(now)}
        m = metrics.update(m, prev, state, info, jnp.asarray(t == done_at), params)
        prev = state
    robot, episode = metrics.finalize(m, prev, params)
    return ({k: np.asarray(v) for k, v in robot.items()},
            {k: float(v) for k, v in episode.items()})


@pytest.mark.slow
def test_straight_path_at_constant_speed():
    env, params = room(num_agents=1)
    # At rest at x = -3, then 1 m/s along +x for 10 steps of 0.1 s.
    frames = [place(env, params, [-3.0 + 0.1 * t], [0.0], speeds=[0.0 if t == 0 else 1.0])
              for t in range(11)]
    robot, episode = play(env, params, frames)
    assert robot["path_length"][0] == pytest.approx(1.0, abs=1e-5)
    assert robot["path_irregularity"][0] == pytest.approx(0.0, abs=1e-6)
    assert robot["stop_time"][0] == 0.0 and robot["freezes"][0] == 0
    assert robot["velocity_change_sum"][0] == pytest.approx(1.0, abs=1e-5)
    assert robot["velocity_change_max"][0] == pytest.approx(1.0, abs=1e-5)
    # Acceleration 10 m/s^2 on the first step, 0 after: mean 1, max 10; jerk 100 once.
    assert robot["acceleration_max"][0] == pytest.approx(10.0, rel=1e-4)
    assert robot["acceleration_mean"][0] == pytest.approx(1.0, rel=1e-4)
    assert robot["jerk_max"][0] == pytest.approx(100.0, rel=1e-4)
    assert robot["jerk_mean"][0] == pytest.approx(100.0 / 9, rel=1e-4)
    assert math.isnan(robot["min_distance_robot"][0])  # alone: no other body
    assert math.isnan(robot["min_distance_human"][0])
    assert robot["min_ttc"][0] == metrics.DEFAULT_CONSTANTS.ttc_cap
    assert robot["success"][0] == 0.0 and robot["timeout"][0] == 1.0
    assert math.isnan(robot["time_to_goal"][0])
    assert episode["episode_length"] == 10 and episode["team_success"] == 0.0


def test_turning_in_place_counts_rotation():
    env, params = room(num_agents=1)
    headings = [0.0, 0.5, 1.0, 3.0, -2.5]  # the last change wraps: 3.0 -> -2.5 is 0.783 rad
    frames = [place(env, params, [0.0], [0.0], headings=[h]) for h in headings]
    robot, _ = play(env, params, frames)
    expected = 0.5 + 0.5 + 2.0 + (2 * math.pi - 5.5)
    assert robot["path_irregularity"][0] == pytest.approx(expected, abs=1e-5)
    assert math.isnan(robot["path_irregularity_per_m"][0])  # did not move


def test_stop_of_known_length_freezes_once_and_deadlocks_two_robots():
    env, params = room(num_agents=2)
    moving = [place(env, params, [-3.0 + 0.1 * t, 3.0 - 0.1 * t], [0.0, 2.0],
                    headings=[0.0, math.pi], speeds=[1.0, 1.0]) for t in range(3)]
    still = place(env, params, [-2.8, 2.8], [0.0, 2.0], headings=[0.0, math.pi])
    robot, episode = play(env, params, moving + [still] * 25)  # 25 stopped steps = 2.5 s
    assert robot["stop_time"] == pytest.approx([2.5, 2.5], abs=1e-5)
    assert robot["freezes"].tolist() == [1.0, 1.0]  # one stop of >= 1 s each
    assert episode["deadlock"] == 0.0  # 2.5 s < 5 s
    _, episode = play(env, params, moving + [still] * 50)
    assert episode["deadlock"] == 1.0


def test_arrival_gives_time_to_goal_spl_and_aggregated_time():
    env, params = room(num_agents=2)
    frames = [place(env, params, [-3.0 + 0.5 * t, -3.0], [0.0, 3.0], speeds=[1.0, 0.0])
              for t in range(6)]
    robot, episode = play(env, params, frames, arrived={4: [0], 5: [1]})
    assert robot["success"].tolist() == [1.0, 1.0]
    assert robot["time_to_goal"] == pytest.approx([0.4, 0.5])
    # Robot 0 drove 2 m (4 steps; it is absorbed after arriving), robot 1 never moved.
    assert robot["path_length"] == pytest.approx([2.0, 0.0], abs=1e-5)
    route = float(frames[0].route.cum_length[0, -1])  # node 0 -> 1 via the centre: 8 m
    assert robot["spl"] == pytest.approx([1.0, 1.0])  # shorter than the route: capped at 1
    assert route == pytest.approx(8.0)
    assert episode["team_success"] == 1.0 and episode["aggregated_time"] == pytest.approx(0.5)


def test_spl_of_a_detour():
    env, params = room(num_agents=1)
    # A zig-zag 0.5 m per step, 20 steps = 10 m for an 8 m route.
    frames = [place(env, params, [-3.0 + 0.3 * t], [0.4 * (t % 2)]) for t in range(21)]
    robot, _ = play(env, params, frames, arrived={20: [0]})
    assert robot["path_length"][0] == pytest.approx(10.0, rel=1e-4)
    assert robot["spl"][0] == pytest.approx(0.8, rel=1e-4)


def test_closest_approach_and_personal_space():
    env, params = room(num_agents=2)
    radius = float(params.robots.radius[0])
    # Two robots pass each other 1.2 m apart (centres), crossing at x = 0 on step 5.
    frames = [place(env, params, [-0.5 + 0.1 * t, 0.5 - 0.1 * t], [0.0, 1.2],
                    headings=[0.0, math.pi], speeds=[1.0, 1.0]) for t in range(11)]
    robot, _ = play(env, params, frames)
    assert robot["min_distance_robot"] == pytest.approx([1.2 - 2 * radius] * 2, abs=1e-5)
    gaps = [math.hypot(1.0 - 0.2 * t, 1.2) - 2 * radius for t in range(1, 11)]
    for k, space in enumerate(metrics.SPACE_NAMES):
        want = np.mean([g < metrics.DEFAULT_CONSTANTS.space_radii[k] for g in gaps])
        assert robot[f"{space}_space_robot"] == pytest.approx([want, want]), space
    assert math.isnan(robot["intimate_space_human"][0])


@pytest.mark.slow
def test_pedestrian_gap_and_time_to_collision():
    env, params = room(num_agents=1, num_humans=1, max_humans=1)
    radius = float(params.robots.radius[0])
    human_radius = float(params.humans.radius)
    # Robot at rest at the origin; a pedestrian 3 m ahead walks at it at 1 m/s.
    frames = [place(env, params, [0.0], [0.0], humans=[(3.0 - 0.1 * t, 0.0, -1.0, 0.0)])
              for t in range(6)]
    robot, _ = play(env, params, frames)
    gap = 2.5 - radius - human_radius  # closest, on the last step
    assert robot["min_distance_human"][0] == pytest.approx(gap, abs=1e-5)
    assert robot["min_ttc"][0] == pytest.approx(gap / 1.0, abs=1e-4)
    assert robot["personal_space_human"][0] == pytest.approx(
        np.mean([2.9 - 0.1 * t - radius - human_radius < 1.2 for t in range(5)]))


def test_time_to_collision_cases():
    ttc = metrics.time_to_collision
    assert float(ttc(4.0, 0.0, -2.0, 0.0, 1.0)) == pytest.approx(1.5)  # head on: (4 - 1) / 2
    assert float(ttc(0.5, 0.0, 1.0, 0.0, 1.0)) == 0.0  # already touching
    assert float(ttc(4.0, 0.0, 2.0, 0.0, 1.0)) == math.inf  # moving apart
    assert float(ttc(4.0, 3.0, -1.0, 0.0, 1.0)) == math.inf  # passes 3 m wide
    assert float(ttc(4.0, 0.5, -1.0, 0.0, 1.0)) == pytest.approx(4.0 - math.sqrt(0.75))


def test_touching_within_float_rounding_is_touching():
    """Bodies the bumpers stopped against each other rest within float32 rounding of touching
    (~4e-7 m either way): time-to-collision 0, not "never" (TOUCHING = 1e-5 m)."""
    ttc = metrics.time_to_collision
    reach = 0.6
    for gap in (-4e-7, 0.0, 4e-7, 9e-6):
        assert float(ttc(jnp.float32(reach + gap), 0.0, 0.0, 0.0, reach)) == 0.0, gap
    assert float(ttc(jnp.float32(reach + 1e-3), 0.0, 0.0, 0.0, reach)) == math.inf  # apart


def test_clean_success_counts_collisions_before_arrival_only():
    """socialnav.md C1: success with no collision *before* reaching the goal. Robot 0 bumps a
    wall while still driving (not clean); robot 1 bumps one after it arrived, while settling
    (clean); both arrive."""
    env, params = room(num_agents=2)
    frames = [place(env, params, [-3.0, 3.0], [0.0, 0.0]) for _ in range(6)]

    def bumped(frame, counts):
        return frame.replace(collisions=CollisionCounts(
            robot=jnp.asarray([0, 0]), wall=jnp.asarray(counts), human=jnp.asarray([0, 0])))

    frames = (frames[:2] + [bumped(f, [1, 0]) for f in frames[2:4]]
              + [bumped(f, [1, 1]) for f in frames[4:]])
    robot, episode = play(env, params, frames, arrived={3: [0, 1]})
    assert robot["success"].tolist() == [1.0, 1.0]
    assert robot["clean_success"].tolist() == [0.0, 1.0]
    assert robot["collisions"].tolist() == [1, 1]


def test_collision_counts_come_from_the_final_state():
    env, params = room(num_agents=2)
    frames = [place(env, params, [-3.0, 3.0], [0.0, 0.0]) for _ in range(3)]
    last = frames[-1].replace(collisions=CollisionCounts(
        robot=jnp.asarray([1, 1]), wall=jnp.asarray([0, 2]), human=jnp.asarray([0, 0])))
    robot, episode = play(env, params, frames[:-1] + [last])
    values = metrics.per_episode(robot, episode)
    assert float(values["collisions"]) == 4 and float(values["collisions_wall"]) == 2
    assert float(values["collision_episode"]) == 1.0
    assert float(values["clean_success"]) == 0.0


def test_order_violation_on_entry_out_of_turn():
    env, params = room(num_agents=2)
    env = SocialNavEnv(dataclasses.replace(env.config, track_zones=True), params)
    rect = params.map.zone_rect
    radius = params.robots.radius
    before = place(env, params, [-1.6, -3.0], [0.0, 0.0])
    # Robot 1 is due first; robot 0 is nearer the zone and goes in anyway.
    before = before.replace(zones=before.zones.replace(
        priority_key=jnp.asarray([[0.9], [0.1]])))
    after = place(env, params, [-1.0, -3.0], [0.0, 0.0])
    after = after.replace(zones=update_zones(before.zones, after.robots.x, after.robots.y,
                                             radius, rect, jnp.int32(1)))
    robot, _ = play(env, params, [before, after])
    assert robot["order_violations_entry"].tolist() == [1.0, 0.0]
    assert robot["order_violations_exit"].tolist() == [0.0, 0.0]
    # Without zone books the metric is undefined, not zero.
    env_plain, params_plain = room(num_agents=2)
    robot, _ = play(env_plain, params_plain, [place(env_plain, params_plain, [0.0, 2.0],
                                                    [0.0, 0.0])] * 2)
    assert math.isnan(robot["order_violations_entry"][0])


def test_nothing_changes_after_the_episode_ended():
    env, params = room(num_agents=1)
    frames = [place(env, params, [-3.0 + 0.1 * t], [0.0], speeds=[1.0]) for t in range(8)]
    robot_early, episode_early = play(env, params, frames[:4], done_at=3)
    robot_late, episode_late = play(env, params, frames, done_at=3)
    assert robot_late["path_length"][0] == pytest.approx(robot_early["path_length"][0])
    assert episode_late["episode_length"] == episode_early["episode_length"] == 3


def test_wilson_and_t_intervals_match_hand_values():
    low, high = wilson_interval(5, 10)
    assert (low, high) == pytest.approx((0.2366, 0.7634), abs=1e-4)
    low, high = wilson_interval(0, 25)
    assert low == pytest.approx(0.0, abs=1e-12) and high == pytest.approx(0.1332, abs=1e-4)
    low, high = t_interval(np.array([1.0, 2.0, 3.0, 4.0, 5.0]))
    half = 2.776445 * math.sqrt(2.5) / math.sqrt(5)
    assert (low, high) == pytest.approx((3 - half, 3 + half), abs=1e-4)
    s = summarize(np.array([0.2, np.nan, 0.4]), binary=False, fraction=True)
    assert s.n == 2 and s.mean == pytest.approx(0.3) and s.ci_low == 0.0  # clipped at 0
    assert summarize(np.array([np.nan]), binary=True).n == 0


DOCS = Path(__file__).resolve().parents[2] / "docs" / "metrics.md"


def test_paired_difference_seed_aggregate_and_interquartile_mean():
    """Paired: the t interval of the per-episode differences, NaN pairs left out; it is narrower
    than the unpaired one when the episodes' difficulty is shared. Seeds: mean and IQM with
    percentile-bootstrap intervals that contain them."""
    a = np.array([1.0, 1.0, 0.0, 1.0, np.nan, 1.0])
    b = np.array([0.0, 1.0, 0.0, 0.0, 1.0, 0.0])
    d = paired_difference(a, b)
    diff = np.array([1.0, 0.0, 0.0, 1.0, 1.0])
    assert d.n == 5 and d.mean == pytest.approx(0.6)
    assert (d.ci_low, d.ci_high) == pytest.approx(t_interval(diff))
    with pytest.raises(ValueError, match="do not pair"):
        paired_difference(a, b[:3])
    assert interquartile_mean(np.arange(8.0)) == pytest.approx(3.5)  # middle half: 2, 3, 4, 5
    agg = seed_aggregate(np.array([0.9, 0.8, 0.95, 0.7, 0.92, 0.1]))
    assert agg["seeds"] == 6 and agg["iqm"] > agg["mean"]  # the outlying seed weighs less
    for name in ("mean", "iqm"):
        assert agg[f"{name}_low"] <= agg[name] <= agg[f"{name}_high"]
    assert math.isnan(seed_aggregate(np.array([0.5]))["mean_low"])


def test_docs_tables_agree_with_the_registry():
    """docs/metrics.md's constants and definitions tables are those the registry generates
    (``python -m sgjax.evaluation.metrics.catalogue`` rewrites them), so every registered
    metric is documented once, with its unit, level, definition and source."""
    text = DOCS.read_text()
    assert catalogue.render(text) == text, (
        "docs/metrics.md is out of date: run python -m sgjax.evaluation.metrics.catalogue")
    for info in metrics.METRICS:
        assert text.count(f"| `{info.name}` |") == 1, info.name
    assert len(set(metrics.METRICS.names())) == len(metrics.METRICS) == 53
    assert catalogue.main([str(DOCS), "--check"]) == 0


def test_the_registry_rejects_incomplete_or_repeated_metrics():
    class Repeats(metrics.Metric):
        infos = (metrics.robot_metric("success", "fraction", "again", "here"),)

    class NoSource(metrics.Metric):
        infos = (metrics.robot_metric("unsourced", "m", "a distance", ""),)

    class BadLevel(metrics.Metric):
        infos = (metrics.MetricInfo("sideways", "m", "team", definition="x", source="y"),)

    for cls, message in ((Repeats, r"repeats metric names \['success'\]"),
                         (NoSource, "'unsourced': source must not be empty"),
                         (BadLevel, "'sideways': level must be one of")):
        with pytest.raises(ValueError, match=message):
            metrics.register_metric(cls)
    with pytest.raises(TypeError, match="Metric subclass"):
        metrics.register_metric(object)
    assert "sideways" not in metrics.METRICS and metrics.METRICS["spl"].unit == "fraction"
    with pytest.raises(KeyError, match="no metric or family"):
        metrics.unregister_metric("never_registered")


class ToyMetric(metrics.Metric):
    """A metric from outside sgjax: each robot's active steps, and the episode in seconds."""

    infos = (
        metrics.robot_metric("toy_active_steps", "steps", "steps the robot was active",
                             "this test", reduce="sum"),
        metrics.episode_metric("toy_seconds", "s", "episode length x dt", "this test"),
    )

    def start(self, num_robots, num_zones, constants):
        return jnp.zeros(num_robots, jnp.int32)

    def update(self, tally, view):
        return view.add(tally, 1)

    def finalize(self, tally, end):
        return {"toy_active_steps": tally, "toy_seconds": end.length * end.dt}


@pytest.fixture
def toy_metric():
    metrics.register_metric(ToyMetric)
    try:
        yield ToyMetric
    finally:
        metrics.unregister_metric(ToyMetric)


def test_a_metric_registered_from_outside_reaches_run_episodes(toy_metric):
    """Registering a Metric subclass is all it takes: ``run_episodes`` reports its values per
    robot (NaN for robot slots not in the episode) and per episode, and unregistering removes
    it again."""
    assert metrics.METRICS.names()[-2:] == ("toy_active_steps", "toy_seconds")
    env, params = make_room(num_agents=2, max_agents=3, dt=DT, time_limit=2.0)
    batch = run_episodes(env, params, "only_local", jax.random.key(0), 2)
    steps = batch.robot["toy_active_steps"]
    assert steps.shape == (2, 3) and np.isnan(steps[:, 2]).all()
    assert (steps[:, :2] >= 1).all() and (steps[:, :2] <= batch.values["episode_length"][:, None]
                                          ).all()
    np.testing.assert_allclose(batch.values["toy_active_steps"], steps[:, :2].sum(axis=1))
    np.testing.assert_allclose(batch.values["toy_seconds"],
                               batch.values["episode_length"] * DT, rtol=1e-6)
    metrics.unregister_metric(ToyMetric)
    assert "toy_seconds" not in metrics.METRICS and len(metrics.METRICS) == 53
    metrics.register_metric(ToyMetric)  # for the fixture to remove


def test_the_docs_example_registers_and_unregisters():
    """The example of docs/metrics.md ("Adding a metric") runs as printed."""
    text = DOCS.read_text()
    section = text[text.index("## Adding a metric"):]
    code = section[section.index("```python\n") + 10:section.index("\n```\n")]
    names = metrics.METRICS.names()
    namespace = {}
    exec(compile(code, "docs/metrics.md", "exec"), namespace)
    assert metrics.METRICS.names() == names  # registered, then unregistered
    metrics.register_metric(namespace["CloseCalls"])
    try:
        assert metrics.METRICS["close_calls"].reduce == "sum"
    finally:
        metrics.unregister_metric("close_calls")


def test_invalid_actions_count_the_steps_a_policy_sent_nan():
    """A policy whose robot 0 sends NaN commands (inside jit, where the environment takes the
    neutral action and flags it) shows it in the evaluator: invalid_actions of robot 0 is the
    number of steps it was active, 0 for the others, and the episode's value their sum."""
    import jax.numpy as jnp

    import sgjax
    from sgjax.evaluation.evaluate import run_episodes

    env, params = sgjax.make("open", num_agents=2, action_mode="continuous", time_limit=4.0)

    def nan_for_robot_zero(obs, key, state, params):
        actions = jnp.zeros((env.max_agents, env.config.action_dim))
        return actions.at[0].set(jnp.nan)

    episodes = run_episodes(env, params, nan_for_robot_zero, jax.random.PRNGKey(0), 3,
                            record=True)
    counts = episodes.robot["invalid_actions"]
    active = np.asarray(episodes.states.robots.active)  # [T + 1, E, R], the reset first
    assert np.all(counts[:, 1] == 0)
    # robot 0 never moves, so every episode runs to its time limit: active before each step
    np.testing.assert_array_equal(counts[:, 0], active[:-1, :, 0].sum(axis=0))
    np.testing.assert_array_equal(episodes.values["invalid_actions"], counts.sum(axis=1))
    assert counts[:, 0].min() > 0
