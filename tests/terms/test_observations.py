"""Observation terms on hand-built scenes, with answers worked out by hand, and the Observer."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scenes import make_room, place

from sgjax.kernels import zone_books as zn
from sgjax.observations import OBSERVATIONS, Lidar, Observer, Others
from sgjax.observations.lidar import beam_angles
from sgjax.terms.base import ConfigError
from sgjax.terms.contract import TermInput
from sgjax.types import Layout

KEY = jax.random.key(0)


def inputs(env, params, state, key=KEY):
    """The one term input of observation terms for ``state``."""
    return TermInput.observing(state, params, env.config.layout, key)


def term_value(spec, env, params, state):
    term = Observer.parse([spec]).terms[0]
    return np.asarray(term(inputs(env, params, state)))


@pytest.fixture(scope="module")
def room():
    return make_room(num_agents=3, max_agents=4, num_humans=2)


def test_pose_with_and_without_heading(room):
    env, params = room
    state = place(env, params, [1.0], [2.0], [math.pi / 2])
    np.testing.assert_allclose(term_value("pose", env, params, state)[0], [1, 2, 0, 1],
                               atol=1e-6)
    value = term_value({"pose": {"heading": False}}, env, params, state)
    np.testing.assert_allclose(value[0], [1, 2])


@pytest.mark.slow
def test_velocity_frames_and_history():
    env, params = make_room(num_agents=1, observations=[{"velocity": {"history": 2}}])
    state = place(env, params, [0.0], [0.0], [math.pi / 2], speeds=[1.0])
    body = term_value({"velocity": {"frame": "body"}}, env, params, state)
    world = term_value({"velocity": {"frame": "world", "turn_rate": False}}, env, params, state)
    np.testing.assert_allclose(body[0], [1, 0, 0], atol=1e-6)
    np.testing.assert_allclose(world[0], [0, 1], atol=1e-6)
    # History: the robot slows to 0.5 m/s; latest first, then the initial one.
    slower = state.robots.replace(kin=state.robots.kin.replace(v_forward=jnp.full(1, 0.5)))
    hist = state.history.push(state.robots, jnp.zeros(1))
    state = state.replace(robots=slower, history=hist)
    value = term_value({"velocity": {"history": 2, "turn_rate": False}}, env, params, state)
    np.testing.assert_allclose(value[0], [0.5, 0, 1, 0], atol=1e-6)
    assert Observer.parse([{"velocity": {"history": 3}}]).terms[0].size(env.config.layout) == 9
    with pytest.raises(ValueError, match="keeps a history of 2 steps"):
        term_value({"velocity": {"history": 3}}, env, params, state)
    # Through the step: the row after the current one is what the robot had before the step.
    before = place(env, params, [0.0], [0.0], [math.pi / 2], speeds=[1.0])
    _, after, *_ = env.step_env(KEY, before, jnp.ones(1, jnp.int32), params)
    value = term_value({"velocity": {"history": 2}}, env, params, after)[0]
    np.testing.assert_allclose(value[3:], [1, 0, 0], atol=1e-6)
    assert value[0] < 1.0  # STOP braked


def test_goal_frames_and_distance(room):
    env, params = room
    # Facing +y at the origin; the goal (node 1) is at (4, 0): 4 m to the robot's right.
    state = place(env, params, [0.0], [0.0], [math.pi / 2], goals=[1])
    np.testing.assert_allclose(term_value({"goal": {"frame": "world"}}, env, params, state)[0],
                               [4, 0])
    np.testing.assert_allclose(term_value({"goal": {"frame": "robot"}}, env, params, state)[0],
                               [0, -4], atol=1e-5)
    np.testing.assert_allclose(term_value("goal_distance", env, params, state)[0], [4])


def test_flags_preferred_speed_and_time_left(room):
    env, params = room
    state = place(env, params, [0.0, 2.0], [0.0, 0.0])
    state = state.replace(touching_wall=state.touching_wall.at[1].set(True),
                          robots=state.robots.replace(
                              succeeded=state.robots.succeeded.at[0].set(True)),
                          time=params.max_steps // 4)
    np.testing.assert_array_equal(term_value("collision", env, params, state)[:2, 0], [0, 1])
    np.testing.assert_array_equal(term_value("success", env, params, state)[:2, 0], [1, 0])
    top = float(params.robots.max_speed[0])
    assert term_value("preferred_speed", env, params, state)[0, 0] == pytest.approx(top)
    assert term_value({"preferred_speed": {"speed": 1.2}}, env, params,
                      state)[0, 0] == pytest.approx(1.2)
    assert term_value("time_left", env, params, state)[0, 0] == pytest.approx(0.75, abs=0.01)


def test_waypoint_is_the_next_route_node(room):
    env, params = room
    # Route 0 -> 4 -> 1: (-4, 0), (0, 0), (4, 0). At the start the next node is the hub.
    state = place(env, params, [-4.0], [0.0], [0.0], starts=[0], goals=[1])
    np.testing.assert_allclose(term_value("waypoint", env, params, state)[0], [4, 0], atol=1e-5)
    # Past the hub (progress 5 m), the next node is the goal: 3 m ahead.
    state = place(env, params, [1.0], [0.0], [0.0], starts=[0], goals=[1])
    state = state.replace(progress=state.progress.at[0].set(5.0))
    np.testing.assert_allclose(term_value("waypoint", env, params, state)[0], [3, 0], atol=1e-5)


def test_others_nearest_first_in_robot_frame(room):
    env, params = room
    r, rh = float(params.robots.radius[0]), float(params.humans.radius)
    # Robot 0 at the origin facing +x; robot 1 at (2, 0); robot 2 at (0, -1) facing -x;
    # a pedestrian at (0, 3) walking +x at 1 m/s.
    state = place(env, params, [0.0, 2.0, 0.0], [0.0, 0.0, -1.0], [0.0, 0.0, math.pi],
                  humans=[(0.0, 3.0, 1.0, 0.0)])
    term = Others(k=4)
    value = np.asarray(term(inputs(env, params, state)))[0].reshape(4, term.width)
    # features: position(2) distance heading(2) velocity(2) radius kind mask
    np.testing.assert_allclose(value[0], [0, -1, 1 - 2 * r, -1, 0, 0, 0, r, 0, 1], atol=1e-5)
    np.testing.assert_allclose(value[1], [2, 0, 2 - 2 * r, 1, 0, 0, 0, r, 0, 1], atol=1e-5)
    np.testing.assert_allclose(value[2], [0, 3, 3 - r - rh, 1, 0, 1, 0, rh, 1, 1], atol=1e-5)
    np.testing.assert_array_equal(value[3], np.zeros(term.width))  # padding
    # Robot 2 faces -x: robot 0 (at (0, 1) relative, world) is to its right.
    value2 = np.asarray(term(inputs(env, params, state)))[2].reshape(4, term.width)
    np.testing.assert_allclose(value2[0, :2], [0, -1], atol=1e-5)


def test_others_goal_is_where_the_other_robot_is_going(room):
    """``features: [..., goal]``: the other robot's goal from the observer, in its frame;
    zeros for a pedestrian. Not part of the default features (sizes unchanged)."""
    env, params = room
    # Robot 0 at (1, 0) facing +y; robot 1 at (2, 0); a pedestrian at (0, 3).
    state = place(env, params, [1.0, 2.0, -3.0], [0.0, 0.0, 0.0], [math.pi / 2, 0.0, 0.0],
                  humans=[(0.0, 3.0, 0.0, 0.0)])
    goal_x, goal_y = np.asarray(state.route.x[:, -1]), np.asarray(state.route.y[:, -1])
    term = Others(k=3, features=("position", "goal"))
    value = np.asarray(term(inputs(env, params, state)))[0].reshape(3, 4)
    # facing +y, world (dx, dy) reads (dy, -dx) in the robot's frame
    dx, dy = goal_x[1] - 1.0, goal_y[1] - 0.0
    np.testing.assert_allclose(value[0], [0, -1, dy, -dx], atol=1e-5)  # robot 1, nearest
    np.testing.assert_allclose(value[1], [3, 1, 0, 0], atol=1e-5)  # the pedestrian
    assert Others().width == Others(features=("position", "distance", "heading", "velocity",
                                              "radius", "kind", "mask")).width == 10
    with pytest.raises(ValueError, match="unknown feature 'goals'"):
        Others(features=("goals",))


def test_others_masks_absent_and_filtered_bodies(room):
    env, params = room
    state = place(env, params, [0.0, 2.0], [0.0, 0.0], humans=[(0.0, 3.0, 0.0, 0.0)])
    robots_only = Others(k=3, humans=False, features=("position", "mask"))
    value = np.asarray(robots_only(inputs(env, params, state)))[0].reshape(3, 3)
    np.testing.assert_allclose(value, [[2, 0, 1], [0, 0, 0], [0, 0, 0]], atol=1e-6)
    near = Others(k=2, max_range=2.5, features=("mask",))
    value = np.asarray(near(inputs(env, params, state)))[0]
    np.testing.assert_array_equal(value, [1, 0])
    # A robot that reached its goal has left the world: others no longer see it.
    done = state.replace(robots=state.robots.replace(
        succeeded=state.robots.succeeded.at[1].set(True)))
    value = np.asarray(robots_only(inputs(env, params, done)))[0]
    np.testing.assert_array_equal(value, np.zeros(9))


def test_others_line_of_sight():
    from scenes import ROOM

    import sgjax
    from sgjax.maps import parse_map
    room = dict(ROOM, walls=ROOM["walls"] + [[1.0, -2.0, 1.0, 2.0]], name="screened",
                zones=[], nodes=[{"id": 0, "position": [-4.0, 3.0]},
                                 {"id": 1, "position": [4.0, 3.0]},
                                 {"id": 2, "position": [-4.0, -3.0]},
                                 {"id": 3, "position": [4.0, -3.0]},
                                 {"id": 4, "position": [0.0, 3.0]}],
                edges=[[0, 4], [1, 4], [2, 0], [3, 1]],
                groups=[{"starts": [0, 1, 2, 3], "goals": [0, 1, 2, 3]}])
    env, params = sgjax.make(parse_map(room), num_agents=3)
    state = place(env, params, [0.0, 2.0, -1.0], [0.0, 0.0, 0.0])
    seen = Others(k=2, features=("position", "mask"), line_of_sight=True)
    value = np.asarray(seen(inputs(env, params, state)))
    # Robot 1 is behind the wall at x = 1 from robot 0; robot 2 is in view.
    np.testing.assert_allclose(value[0], [-1, 0, 1, 0, 0, 0], atol=1e-6)
    np.testing.assert_allclose(value[1], [0, 0, 0, 0, 0, 0], atol=1e-6)


def test_others_with_variable_robot_counts():
    env, params = make_room(num_agents=2, max_agents=4)
    term = Others(k=3, humans=False, features=("mask",))
    for n in (1, 2, 3, 4):
        p = params.replace(num_agents=jnp.asarray(n, jnp.int32))
        state = place(env, p, [0.0, 1.0, 2.0, 3.0][:n], [0.0] * n)
        mask = np.asarray(term(inputs(env, p, state)))
        np.testing.assert_array_equal(mask[:n].sum(axis=1), [min(n - 1, 3)] * n)
        obs = np.asarray(env.observe(state, p))
        assert (obs[n:] == 0).all()  # the Observer zeroes absent robots' rows


def test_lidar_against_a_wall_and_a_robot(room):
    env, params = room
    r = float(params.robots.radius[0])
    state = place(env, params, [0.0, -2.0], [0.0, 0.0], [0.0, 0.0])
    lidar = Lidar(beams=4, range=10.0)
    angles = np.asarray(beam_angles(4, 2 * math.pi))
    np.testing.assert_allclose(angles, [-math.pi, -math.pi / 2, 0, math.pi / 2])
    value = np.asarray(lidar(inputs(env, params, state)))[0]
    # Behind: robot 1's disc at 2 - r; right and left: walls at 5 m; ahead: the wall at x = 5.
    np.testing.assert_allclose(value, [2 - r, 5, 5, 5], atol=1e-5)
    capped = Lidar(beams=4, range=3.0)
    np.testing.assert_allclose(np.asarray(capped(inputs(env, params, state)))[0],
                               [2 - r, 3, 3, 3], atol=1e-5)
    noisy = Lidar(beams=4, range=10.0, noise=0.01)
    a = np.asarray(noisy(inputs(env, params, state, jax.random.key(1))))[0]
    b = np.asarray(noisy(inputs(env, params, state, jax.random.key(2))))[0]
    assert np.abs(a - value).max() < 0.05 and not np.allclose(a, b)


def test_lidar_sees_pedestrians_and_turns_with_the_robot(room):
    env, params = room
    rh = float(params.humans.radius)
    state = place(env, params, [0.0], [0.0], [math.pi / 2], humans=[(0.0, 2.0, 0.0, 0.0)])
    value = np.asarray(Lidar(beams=4, range=10.0)(inputs(env, params, state)))[0]
    # Facing +y: beam 2 (straight ahead) meets the pedestrian.
    np.testing.assert_allclose(value[2], 2 - rh, atol=1e-5)
    np.testing.assert_allclose(value[[0, 1, 3]], [5, 5, 5], atol=1e-5)


def test_zone_bookkeeping_by_hand():
    rect = jnp.asarray([[-1.0, -1.0, 1.0, 1.0]])
    radius = jnp.full(3, 0.25)
    # Robot 0 straddles the left edge, robot 1 is wholly inside, robot 2 is 2 m out.
    x, y = jnp.asarray([-1.1, 0.0, -3.25]), jnp.zeros(3)
    np.testing.assert_array_equal(zn.overlaps(x, y, radius, rect)[:, 0], [True, True, False])
    np.testing.assert_array_equal(zn.contained(x, y, radius, rect)[:, 0], [False, True, False])
    np.testing.assert_allclose(zn.disc_rect_distance(x, y, rect)[:, 0], [0.1, 0, 2.25],
                               atol=1e-6)
    route_x = jnp.asarray([[-4.0, 4.0], [-4.0, 4.0], [-4.0, -4.0]])
    route_y = jnp.asarray([[0.0, 0.0], [0.0, 0.0], [3.0, 4.0]])
    crosses = zn.route_crosses_rects(route_x, route_y, rect, radius)
    np.testing.assert_array_equal(crosses[:, 0], [True, True, False])
    zones = zn.ZoneState(
        participant=jnp.asarray([[True], [True], [True]]),
        priority_key=jnp.asarray([[0.5], [0.9], [0.1]]),
        phase=jnp.asarray([[zn.INSIDE], [zn.INSIDE], [zn.BEFORE]]),
        was_contained=jnp.asarray([[False], [True], [False]]),
        entered_at=jnp.asarray([[7], [3], [0]]),
    )
    # Priority among those still to pass: robot 2 (0.1), robot 0 (0.5), robot 1 (0.9).
    np.testing.assert_array_equal(zn.priority_rank(zones)[:, 0], [1, 2, 0])
    # Queue: inside by entry time (robot 1 entered first), then robot 2 outside.
    np.testing.assert_array_equal(zn.current_rank(zones, x, y, rect)[:, 0], [1, 0, 2])
    entering, exiting = zn.straddling(zones, x, y, radius, rect)
    np.testing.assert_array_equal(entering[:, 0], [True, False, False])
    # Robot 1 moves out over the right edge: it is exiting, then it has left.
    x2 = jnp.asarray([-1.1, 1.1, -3.25])
    _, exiting = zn.straddling(zones, x2, y, radius, rect)
    np.testing.assert_array_equal(exiting[:, 0], [False, True, False])
    left = zn.update_zones(zones, jnp.asarray([-1.1, 2.0, -3.25]), y, radius, rect, 9)
    np.testing.assert_array_equal(left.phase[:, 0], [zn.INSIDE, zn.LEFT, zn.BEFORE])
    np.testing.assert_array_equal(zn.priority_rank(left)[:, 0], [1, -1, 0])


def test_zone_terms_in_the_room():
    env, params = make_room(num_agents=2, observations=[
        "in_zone", "entering_zone", "exiting_zone", "zone_entering_count", "zone_exiting_count",
        "zone_priority", "zone_order"])
    assert env.observation_size == 7  # one zone
    # Robot 0 straddles the zone's left edge on its way in; robot 1 waits 2 m out.
    state = place(env, params, [-1.1, -3.2], [0.0, 0.0], starts=[0, 0], goals=[1, 1])
    obs = np.asarray(env.observe(state, params))
    parts = {k: v[:, 0] for k, v in env.split_observation(obs).items()}
    np.testing.assert_array_equal(parts["in_zone"][:2], [1, 0])
    np.testing.assert_array_equal(parts["entering_zone"][:2], [1, 0])
    np.testing.assert_array_equal(parts["zone_entering_count"][:2], [1, 1])
    np.testing.assert_array_equal(parts["zone_order"][:2], [0, 1])
    assert sorted(parts["zone_priority"][:2].tolist()) == [0, 1]


def test_zone_ahead_reads_the_zone_terms_at_the_zone_in_front():
    """``zone_ahead`` is the per-zone terms read at the zone the robot is in or the nearest it
    has yet to pass; a robot past every zone reads none ahead."""
    env, params = make_room(num_agents=3, observations=[
        "zone_ahead", "in_zone", "entering_zone", "zone_entering_count", "zone_priority",
        "zone_order"])
    assert env.config.observer.sizes(env.config.layout)["zone_ahead"] == 7
    state = place(env, params, [-1.1, -3.2, 2.0], [0.0, 0.0, 0.0], starts=[0, 0, 0],
                  goals=[1, 1, 1])
    state = state.replace(zones=state.zones.replace(
        phase=state.zones.phase.at[2].set(zn.LEFT)))
    obs = np.asarray(env.observe(state, params))
    parts = env.split_observation(obs)
    ahead = parts["zone_ahead"]
    np.testing.assert_array_equal(ahead[:2, 0], [1, 1])
    np.testing.assert_array_equal(ahead[:2, 2], parts["zone_priority"][:2, 0])
    np.testing.assert_array_equal(ahead[:2, 3], parts["zone_order"][:2, 0])
    np.testing.assert_array_equal(ahead[:2, 4], parts["in_zone"][:2, 0])
    np.testing.assert_array_equal(ahead[:2, 5], parts["entering_zone"][:2, 0])
    np.testing.assert_array_equal(ahead[:2, 6], parts["zone_entering_count"][:2, 0])
    np.testing.assert_allclose(ahead[:2, 1], [0.1, 2.2], atol=1e-5)  # centre to the zone (m)
    np.testing.assert_array_equal(ahead[2], [0, 10, -1, -1, 0, 0, 0])  # past the zone


def test_the_transfer_preset_has_one_size_on_every_world():
    import sgjax

    sizes = {sgjax.make(s, num_agents=3, observation_preset="transfer")[0].observation_size
             for s in ("doorway", "office", "generated:floorplan", "generated:open")}
    assert len(sizes) == 1


def test_observer_slices_sizes_and_split():
    spec = ["pose", {"velocity": {"history": 2}}, {"others": {"k": 2}}, {"lidar": {"beams": 8}}]
    env, params = make_room(num_agents=2, max_agents=4, observations=spec)
    observer = env.config.observer
    cfg = env.config.layout
    assert observer.sizes(cfg) == {"pose": 4, "velocity": 6, "others": 20, "lidar": 8}
    assert observer.size(cfg) == 38 and observer.history_length == 2
    assert observer.slices(cfg)["others"] == slice(10, 30)
    state = place(env, params, [0.0, 2.0], [0.0, 0.0])
    obs = observer(inputs(env, params, state))
    assert obs.shape == (4, 38) and env.observation_space().shape == (38,)
    assert (np.asarray(obs)[2:] == 0).all()  # absent robots observe zeros
    split = observer.split(obs, cfg)
    np.testing.assert_array_equal(split["pose"], obs[:, :4])
    assert "others" in observer.describe(cfg)


def test_terms_publish_their_column_layouts():
    """Each term names its columns; the Observer lays them out over the whole vector, so
    readers (networks, masks) find features by name instead of by the terms' internals."""
    from sgjax.observations import Columns

    spec = [{"pose": {"heading": True}}, {"velocity": {"history": 2, "turn_rate": False}},
            {"others": {"k": 3, "features": ["position", "mask", "goal"]}},
            {"lidar": {"beams": 2}}]
    env, _ = make_room(num_agents=2, max_agents=4, observations=spec)
    layout = env.config.layout
    pose, velocity, others, lidar = env.config.observer.terms
    assert pose.columns(layout).names == ("x", "y", "cos_heading", "sin_heading")
    assert pose.columns(layout).feature_names == ("position", "heading")
    assert velocity.columns(layout).names == ("v_forward[0]", "v_lateral[0]", "v_forward[1]",
                                              "v_lateral[1]")
    block = others.columns(layout)
    assert block.shape == (3, 5) and block.block_names == ("dx", "dy", "mask", "goal_dx",
                                                           "goal_dy")
    assert block.offset("mask") == 2 and block.feature_slice("goal") == slice(3, 5)
    assert block.filled == 3  # 3 other robots + 2 pedestrians can be seen, k = 3
    np.testing.assert_array_equal(block.indices("mask"), [2, 7, 12])
    assert lidar.columns(layout).names == ("range[0]", "range[1]")
    for term in env.config.observer.terms:
        assert len(term.columns(layout)) == term.size(layout)
    columns = env.config.observer.columns(layout)
    assert columns.size == env.observation_size == 4 + 4 + 15 + 2
    assert columns.slices == env.observation_slices()
    assert columns.span("others") == slice(8, 23) and columns["others"] == block
    assert columns.names[:3] == ("pose.x", "pose.y", "pose.cos_heading")
    assert columns.names[8:10] == ("others.dx[0]", "others.dy[0]")
    assert len(columns.names) == len(set(columns.names)) == columns.size
    np.testing.assert_array_equal(columns.indices("pose.heading"), [2, 3])
    np.testing.assert_array_equal(columns.indices("others.mask"), [10, 15, 20])
    np.testing.assert_array_equal(columns.indices("lidar"), [23, 24])
    with pytest.raises(ValueError, match="others: no feature 'heading'.*position, mask, goal"):
        columns.indices("others.heading")
    with pytest.raises(KeyError, match="no observation term 'goal'"):
        columns.indices("goal")
    assert "others" in columns.describe() and "3 x 5" in columns.describe()
    in_zone = Observer.parse(["in_zone"]).terms[0]  # one block per zone of the map
    assert in_zone.columns(Layout(max_agents=2, num_zones=0)).names == ()
    assert in_zone.columns(Layout(max_agents=2, num_zones=2)).names == ("inside[0]", "inside[1]")
    with pytest.raises(ValueError, match="unique"):
        Columns.grouped({"a": ("x",), "b": ("x",)})


def test_observation_config_errors():
    with pytest.raises(ConfigError, match="unknown observation term 'poze'.*did you mean 'pose'"):
        Observer.parse(["poze"])
    with pytest.raises(ConfigError, match="valid observation terms are: .*lidar"):
        Observer.parse(["nope"])
    with pytest.raises(ConfigError, match=r"velocity: unknown option 'histroy'.*history"):
        Observer.parse([{"velocity": {"histroy": 2}}])
    with pytest.raises(ConfigError, match="frame must be one of"):
        Observer.parse([{"goal": {"frame": "map"}}])
    with pytest.raises(ConfigError, match="repeated"):
        Observer.parse(["pose", "pose"])
    with pytest.raises(ConfigError, match="unknown feature"):
        Observer.parse([{"others": {"features": ["speed"]}}])
    with pytest.raises(ConfigError, match="each feature may appear once"):
        Observer.parse([{"others": {"features": ["mask", "mask"]}}])
    with pytest.raises(ConfigError, match=r"observations\[1\]: expected a name or"):
        Observer.parse(["pose", 3])
    with pytest.raises(ConfigError, match="expected a list or mapping of observation terms"):
        Observer.parse("pose")
    assert isinstance(Observer.parse({"pose": None, "goal": {"frame": "world"}}), Observer)
    assert "lidar" in OBSERVATIONS.names()
