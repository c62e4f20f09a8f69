"""The robot-side example (``examples/ros2_policy``): ROS 2 messages built with ``rosbags``'
typestore (serialised to CDR and read back, as a bag replay or a robot would receive them) give
the observation sgjax computed for the same state, term by term (the transfer preset: body
velocity, goal, waypoint, lidar, the nearest robots and people, the zone ahead), and the ONNX
actor on them decides as the JAX actor on sgjax's own observation; actions become velocity
commands as sgjax decodes them; the ``rclpy`` node says so where ROS 2 is missing."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

pytest.importorskip("rosbags")
pytest.importorskip("onnxruntime")
pytest.importorskip("jax2onnx")

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "ros2_policy"
sys.path.insert(0, str(EXAMPLE))

from rosbags.typesys import Stores, get_types_from_msg, get_typestore  # noqa: E402
from sgjax_policy import commands as cmd  # noqa: E402
from sgjax_policy.fleet import FleetController  # noqa: E402
from sgjax_policy.observation import ObservationBuilder  # noqa: E402

import sgjax  # noqa: E402

ROBOTS, HUMANS, STEPS = 3, 4, 60

PERSON = """string name
geometry_msgs/Point position
geometry_msgs/Point velocity
float64 reliability
string[] tagnames
string[] tags
"""
PEOPLE = """std_msgs/Header header
people_msgs/Person[] people
"""


@pytest.fixture(scope="module")
def typestore():
    """ROS 2 Humble's messages and people_msgs (the ``people`` package's definitions)."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register({**get_types_from_msg(PERSON, "people_msgs/msg/Person"),
                    **get_types_from_msg(PEOPLE, "people_msgs/msg/People")})
    return store


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """An actor of the transfer observations among pedestrians in the doorway, exported."""
    trainer_tests = Path(__file__).resolve().parents[1] / "trainer"
    sys.path.insert(0, str(trainer_tests))
    from test_transfer import tiny_run

    from train.export import main

    root = tmp_path_factory.mktemp("ros2")
    run = tiny_run(root / "run", num_seeds=1, scenarios=["doorway"], num_humans=HUMANS,
                   observations="transfer", curriculum=[[0, ROBOTS]])
    main([str(run), "--format", "onnx", "--out", str(root / "actor.onnx")])
    return run, root / "actor.onnx"


@pytest.fixture(scope="module")
def episode(exported):
    """A recorded rollout in the exported actor's environment: states ``[T + 1]`` and
    sgjax's observations ``[T + 1, R, D]`` (random GO/STOP robots)."""
    from train.run.checkpoint import read, resolve

    run, _ = exported
    config, _, _ = read(resolve(run))
    env, params = sgjax.make(config.env.scenarios[0], options=config.env.options,
                             num_agents=ROBOTS, max_agents=config.env.slots)
    obs, state = env.reset(jax.random.key(4), params)

    def step(carry, key):
        obs, state = carry
        k_act, k_step = jax.random.split(key)
        actions = jax.random.bernoulli(k_act, 0.3, (env.max_agents,)).astype(jnp.int32)
        obs, state, *_ = env.step_env(k_step, state, actions, params)
        return (obs, state), (obs, state)

    _, (seen, states) = jax.jit(lambda c: jax.lax.scan(
        step, c, jax.random.split(jax.random.key(5), STEPS)))((obs, state))
    both = jax.tree.map(lambda a, b: np.concatenate([np.asarray(a)[None], np.asarray(b)]),
                        (obs, state), (seen, states))
    return env, params, both[0], both[1]


def _at(tree, t):
    return jax.tree.map(lambda leaf: leaf[t], tree)


def _stamp(store, seconds):
    time = store.types["builtin_interfaces/msg/Time"]
    return store.types["std_msgs/msg/Header"](
        stamp=time(sec=int(seconds), nanosec=int((seconds % 1) * 1e9)), frame_id="map")


def _wire(store, message, kind):
    """``message`` serialised to CDR and read back: what a subscriber receives."""
    return store.deserialize_cdr(store.serialize_cdr(message, kind), kind)


def _messages(store, env, params, state, t):
    """Every message the fleet receives at step ``t`` of the recorded ``state`` (one
    environment, not stacked): per robot odometry, goal, waypoint, scan and zone-ahead values,
    and the people."""
    from sgjax.evaluation.episode_log import episode_scans

    T = store.types
    header = _stamp(store, t * float(params.dt))
    point = T["geometry_msgs/msg/Point"]
    vector = T["geometry_msgs/msg/Vector3"]
    r, route = state.robots, state.route
    heading = np.asarray(r.kin.heading)
    body_v = np.asarray(r.body_velocity)
    scans = episode_scans(jax.tree.map(lambda a: np.asarray(a)[None], state), params,
                          env.config.layout, 1)[0]  # [R, 64] over the full circle, 10 m
    beams = scans.shape[-1]
    out = {"robots": [], "people": None}
    progress, cum = np.asarray(state.progress), np.asarray(route.cum_length)
    for i in range(env.max_agents):
        c, s = math.cos(heading[i]), math.sin(heading[i])
        forward = body_v[i, 0] * c + body_v[i, 1] * s  # the body's velocity, body frame
        lateral = -body_v[i, 0] * s + body_v[i, 1] * c
        quat = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(heading[i] / 2),
                                                 w=math.cos(heading[i] / 2))
        pose = T["geometry_msgs/msg/Pose"](position=point(x=float(r.x[i]), y=float(r.y[i]),
                                                          z=0.0), orientation=quat)
        twist = T["geometry_msgs/msg/Twist"](linear=vector(x=float(forward), y=float(lateral),
                                                           z=0.0),
                                             angular=vector(x=0.0, y=0.0,
                                                            z=float(r.kin.omega[i])))
        odometry = T["nav_msgs/msg/Odometry"](
            header=header, child_frame_id=f"robot_{i}",
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose,
                                                           covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist,
                                                             covariance=np.zeros(36)))
        goal = T["geometry_msgs/msg/PoseStamped"](header=header, pose=T["geometry_msgs/msg/Pose"](
            position=point(x=float(route.goal_x[i]), y=float(route.goal_y[i]), z=0.0),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)))
        ahead = cum[i] > progress[i] + 1e-3  # the global planner's next node
        wx, wy = ((route.x[i][np.argmax(ahead)], route.y[i][np.argmax(ahead)]) if ahead.any()
                  else (route.goal_x[i], route.goal_y[i]))
        waypoint = T["geometry_msgs/msg/PointStamped"](header=header, point=point(
            x=float(wx), y=float(wy), z=0.0))
        scan = T["sensor_msgs/msg/LaserScan"](
            header=header, angle_min=-math.pi, angle_max=math.pi - 2 * math.pi / beams,
            angle_increment=2 * math.pi / beams, time_increment=0.0, scan_time=0.0,
            range_min=0.0, range_max=9.999, ranges=np.asarray(scans[i], np.float32),
            intensities=np.zeros(0, np.float32))
        out["robots"].append({k: _wire(store, v, kind) for k, v, kind in [
            ("odometry", odometry, "nav_msgs/msg/Odometry"),
            ("goal", goal, "geometry_msgs/msg/PoseStamped"),
            ("waypoint", waypoint, "geometry_msgs/msg/PointStamped"),
            ("scan", scan, "sensor_msgs/msg/LaserScan")]})
        out["robots"][-1]["in_world"] = bool(np.asarray(r.in_world)[i])
    h = state.humans
    people = [T["people_msgs/msg/Person"](
        name=f"person_{j}", position=point(x=float(h.x[j]), y=float(h.y[j]), z=0.0),
        velocity=point(x=float(h.vx[j]), y=float(h.vy[j]), z=0.0), reliability=1.0,
        tagnames=[], tags=[]) for j in range(h.x.shape[0]) if bool(h.active[j])]
    out["people"] = _wire(store, T["people_msgs/msg/People"](header=header, people=people),
                          "people_msgs/msg/People")
    return out


def _zone_message(store, values):
    return _wire(store, store.types["std_msgs/msg/Float32MultiArray"](
        layout=store.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0),
        data=np.asarray(values, np.float32)), "std_msgs/msg/Float32MultiArray")


def _feed(fleet, store, env, params, state, obs_row_zone, t):
    msgs = _messages(store, env, params, state, t)
    for i, name in enumerate(fleet.names):
        robot = msgs["robots"][i]
        if not robot["in_world"]:
            fleet.latest[name] = {}
            continue
        fleet.on_odometry(name, robot["odometry"])
        fleet.on_goal(name, robot["goal"])
        fleet.on_waypoint(name, robot["waypoint"])
        fleet.on_scan(name, robot["scan"])
        fleet.on_zone_ahead(name, _zone_message(store, obs_row_zone[i]))
    fleet.on_people(msgs["people"])


@pytest.mark.slow
def test_messages_give_sgjax_observations_and_onnx_decides_as_jax(exported, episode,
                                                                     typestore):
    """Every step of a rollout with pedestrians: the example's observation from the messages
    equals sgjax's (within 1e-4 m; the zone coordinator's values are given), and the ONNX
    actor's decisions on it equal the JAX actor's on sgjax's observation."""
    from train.run.onnx_export import decision_function, load_actor

    run, model = exported
    env, params, obs, states = episode
    _, config, layout, weights, _ = load_actor(run)
    decide = jax.jit(decision_function(config.network, layout, weights))
    names = [f"robot_{i}" for i in range(env.max_agents)]
    fleet = FleetController(model, names)
    zone = fleet.sidecar["observation"]["terms"][-1]
    assert zone["name"] == "zone_ahead"
    compared = humans_seen = 0
    for t in range(STEPS + 1):
        state = _at(states, t)
        _feed(fleet, typestore, env, params, state, obs[t][:, zone["start"]:zone["stop"]], t)
        built = fleet.observations()
        for i in range(env.max_agents):
            if not fleet.ready(names[i]):
                continue
            np.testing.assert_allclose(built[i], obs[t][i], atol=1e-4, rtol=1e-5,
                                       err_msg=f"step {t}, robot {i}")
            compared += 1
        actions, commands = fleet.tick()
        _, jax_actions = decide(jnp.asarray(obs[t]))
        ready = [fleet.ready(n) for n in names]
        np.testing.assert_array_equal(np.asarray(actions)[ready],
                                      np.asarray(jax_actions)[ready])
        humans_seen += int(np.sum(np.asarray(state.humans.active)))
    assert compared >= STEPS * 2 and humans_seen > 0


def test_history_terms_repeat_the_first_value_then_shift():
    """``velocity`` with ``history: 3``: latest first, the first value repeated before the
    episode's start (as sgjax's observation history), cleared by ``start``."""
    from sgjax_policy.messages import Body
    from sgjax_policy.observation import RobotView

    sidecar = {"observation": {"size": 6, "terms": [
        {"name": "velocity", "start": 0, "stop": 6,
         "options": {"frame": "body", "history": 3, "turn_rate": False}}]}}
    builder = ObservationBuilder(sidecar)

    def view(v):
        return RobotView(me=Body(0.0, 0.0, 0.0, v, 0.0, 0.2, False, v_forward=v),
                         goal=(1.0, 0.0))

    assert builder.build(0, view(0.5)).tolist() == [0.5, 0, 0.5, 0, 0.5, 0]
    assert builder.build(0, view(0.7)).tolist() == pytest.approx([0.7, 0, 0.5, 0, 0.5, 0])
    assert builder.build(0, view(0.9)).tolist() == pytest.approx([0.9, 0, 0.7, 0, 0.5, 0])
    builder.start()
    assert builder.build(0, view(0.1)).tolist() == pytest.approx([0.1, 0, 0.1, 0, 0.1, 0])


def test_terms_without_a_robot_side_source_are_refused_by_name():
    for term, words in [({"name": "time_left"}, "time_left"),
                        ({"name": "lidar", "options": {"noise": 0.01}}, "noise")]:
        sidecar = {"observation": {"size": 1, "terms": [{"start": 0, "stop": 1, **term}]}}
        with pytest.raises(ValueError, match=words):
            ObservationBuilder(sidecar)


def test_actions_become_the_commands_sgjax_decodes():
    """GO passes the planner's command on, STOP stops; continuous actions scale by the limits
    as ``sgjax.dynamics.models.decode_continuous`` does (Ackermann: steering as yaw rate)."""
    from sgjax.dynamics.limits import PRESETS, robot_params
    from sgjax.dynamics.models import decode_continuous
    from train.run.onnx_export import robot_limits

    assert cmd.command(0, {}, True, (0.3, 0.0, 0.1)) == (0.3, 0.0, 0.1)
    assert cmd.command(1, {}, True, (0.3, 0.0, 0.1)) == cmd.STOPPED
    assert cmd.command(0, {}, True, None) == cmd.STOPPED
    for kind, dim in [("socialgym", 2), ("cobot", 3), ("automata", 2)]:
        p = robot_params([PRESETS[kind]] * 3)
        limits = robot_limits(p)
        actions = np.array([[0.5, -0.3, 1.0][:dim], [-1.0, 0.2, -0.4][:dim],
                            [2.0, 0.0, 0.7][:dim]], np.float32)
        forward, lateral, turn = (np.asarray(v) for v in decode_continuous(
            jnp.asarray(actions), p, dim))
        for i in range(3):
            vx, vy, wz = cmd.continuous_command(actions[i], limits[i])
            assert vx == pytest.approx(float(forward[i]), abs=1e-6)
            assert vy == pytest.approx(float(lateral[i]), abs=1e-6)
            want = (float(forward[i]) * math.tan(float(turn[i])) / limits[i]["wheelbase"]
                    if kind == "automata" else float(turn[i]))
            assert wz == pytest.approx(want, abs=1e-5)


def test_the_node_says_when_ros2_is_missing():
    """Without rclpy the node exits with status 2 and says what to install (with ROS 2 it runs:
    not exercised here)."""
    try:
        import rclpy  # noqa: F401
        pytest.skip("ROS 2 is installed here: the node would start")
    except ImportError:
        pass
    done = subprocess.run([sys.executable, "-m", "sgjax_policy.node", "--model", "x.onnx",
                           "--robots", "robot_0"], cwd=EXAMPLE, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 2
    assert "ROS 2 is not installed" in done.stderr


def test_sidecar_names_each_term_setting_and_the_robots_limits(exported):
    _, model = exported
    sidecar = json.loads(model.with_suffix(".json").read_text())
    terms = {t["name"]: t for t in sidecar["observation"]["terms"]}
    assert terms["lidar"]["options"]["beams"] == 16
    assert terms["others"]["options"]["k"] == 4
    assert len(sidecar["robots"]) >= ROBOTS
    assert all(r["radius"] > 0 and r["max_speed"] > 0 for r in sidecar["robots"])
    assert sidecar["humans"]["radius"] > 0
