"""Episodes as MCAP files in Foxglove's schemas (``sgjax.evaluation.episode_log``, ``sgjax
render --format mcap``): read back with ``mcap``'s own reader and protobuf decoder, every
topic holds the rollout's values at the simulation clock's times."""

from __future__ import annotations

import json
from collections import defaultdict

import jax
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from sgjax.command import main
from sgjax.environment.options import MakeOptions
from sgjax.evaluation.episode_log import SCAN_BEAMS, episode_scans, write_mcap
from sgjax.evaluation.evaluate import policy_environment, run_episodes
from sgjax.evaluation.policies import load_policy
from sgjax.evaluation.render import recorded_map


def read_back(path):
    """``{topic: [(log_time ns, message)]}``: protobuf messages decoded by ``mcap_protobuf``,
    JSON ones parsed."""
    out = defaultdict(list)
    factory = DecoderFactory()
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            if channel.message_encoding == "json":
                value = json.loads(message.data)
            else:
                value = factory.decoder_for(channel.message_encoding, schema)(message.data)
            out[channel.topic].append((message.log_time, value))
    return out


@pytest.fixture(scope="module")
def episode():
    options = MakeOptions().replace(num_humans=3, time_limit=8.0)
    env, by_count = policy_environment("doorway", [3], "only_local", options)
    params = by_count[3]
    batch = run_episodes(env, params, load_policy("only_local", env), jax.random.key(2), 1,
                         record=True)
    states = jax.tree.map(lambda leaf: leaf[:, 0], batch.states)
    length = int(batch.values["episode_length"][0])
    return env, params, states, length, batch.rewards[:, 0]


def test_recorded_rewards_are_the_steps_rewards():
    """The runner's recorded rewards ``[T, E, R]``: each step's reward as ``env.step_env``
    gives it from the recorded state and the action held after it (robots alone, so the step
    is deterministic), zero once the episode has ended."""
    options = MakeOptions().replace(time_limit=6.0)
    env, by_count = policy_environment("open", [3], "only_local", options)
    params = by_count[3]
    batch = run_episodes(env, params, load_policy("only_local", env), jax.random.key(5), 2,
                         record=True)
    steps = batch.rewards.shape[0]
    assert batch.rewards.shape == (steps, 2, env.max_agents)
    assert jax.tree.leaves(batch.states)[0].shape[0] == steps + 1
    step = jax.jit(env.step_env)
    for e in range(2):
        length = int(batch.values["episode_length"][e])
        for t in range(length):
            before = jax.tree.map(lambda leaf, t=t, e=e: leaf[t, e], batch.states)
            after = jax.tree.map(lambda leaf, t=t, e=e: leaf[t + 1, e], batch.states)
            _, replayed, reward, *_ = step(jax.random.key(0), before, after.held_action, params)
            np.testing.assert_allclose(np.asarray(replayed.robots.x), np.asarray(after.robots.x),
                                       atol=1e-6)
            np.testing.assert_allclose(batch.rewards[t, e], np.asarray(reward), atol=1e-5)
        assert not np.any(batch.rewards[length:, e])
        assert np.any(batch.rewards[:length, e])


def test_an_episode_reads_back_as_the_rollout(tmp_path, episode):
    env, params, states, length, rewards = episode
    spec = recorded_map("doorway", states)
    path = write_mcap(tmp_path / "e.mcap", spec, states, params, env.config.layout, length,
                      rewards=rewards, metrics={"team_success": 1.0})
    topics = read_back(path)
    count = length + 1
    assert {"/map", "/robots", "/pedestrians", "/tf", "/step", "/metrics",
            "/robot_0/scan", "/robot_2/scan"} <= set(topics)
    walls = topics["/map"][0][1].entities[0]
    assert len(walls.lines[0].points) == 2 * len(spec.walls)
    dt_ns = round(float(params.dt) * 1e6) * 1000
    assert [t for t, _ in topics["/tf"]] == [k * dt_ns for k in range(count)]
    scans = episode_scans(states, params, env.config.layout, count)
    for k, (_, tf) in enumerate(topics["/tf"]):
        xy = np.asarray([[f.translation.x, f.translation.y] for f in tf.transforms])
        np.testing.assert_allclose(xy[:, 0], np.asarray(states.robots.x[k]), atol=1e-6)
        np.testing.assert_allclose(xy[:, 1], np.asarray(states.robots.y[k]), atol=1e-6)
        scan = topics["/robot_1/scan"][k][1]
        assert len(scan.ranges) == SCAN_BEAMS
        np.testing.assert_allclose(scan.ranges, scans[k, 1], atol=1e-5)
        people = {e.id: e for e in topics["/pedestrians"][k][1].entities}
        active = np.flatnonzero(np.asarray(states.humans.active[k]))
        assert sorted(people) == sorted(f"pedestrian_{i}" for i in active)
        for i in active:
            pose = people[f"pedestrian_{i}"].cylinders[0].pose.position
            assert pose.x == pytest.approx(float(states.humans.x[k, i]), abs=1e-6)
        robots = topics["/robots"][k][1].entities
        assert len(robots) == int(np.sum(np.asarray(states.robots.in_world[k])))
        step = topics["/step"][k][1]
        assert step["decision"] == np.asarray(states.held_action[k]).tolist()
        assert step["time"] == pytest.approx(k * float(params.dt))
        if k:
            np.testing.assert_allclose(step["reward"], rewards[k - 1], rtol=1e-6)
    assert topics["/metrics"][0][1] == {"team_success": 1.0}


def test_sgjax_render_writes_mcap(tmp_path, capsys):
    out = tmp_path / "episode.mcap"
    main(["render", "--scenario", "open", "--policy", "only_local", "--num-agents", "2",
          "--time-limit", "5", "--out", str(out)])
    topics = read_back(out)
    assert "team_success" in topics["/metrics"][0][1]
    assert len(topics["/tf"]) == len(topics["/step"]) >= 2
    assert "open it in Foxglove" in capsys.readouterr().out
    with pytest.raises(SystemExit, match=r"must end in \.gif, \.mp4 or \.mcap"):
        main(["render", "--scenario", "open", "--out", str(tmp_path / "x.txt")])


def test_an_episode_reads_back_from_a_ros2_bag(tmp_path, episode):
    """rosbags' own reader and typestore: odometry, scans, pedestrians and decisions are the
    rollout's at the simulation clock's times."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    from sgjax.evaluation.episode_bag import write_rosbag2

    env, params, states, length, rewards = episode
    spec = recorded_map("doorway", states)
    path = write_rosbag2(tmp_path / "bag", spec, states, params, env.config.layout, length,
                         rewards=rewards)
    store = get_typestore(Stores.ROS2_HUMBLE)
    topics = defaultdict(list)
    with Reader(path) as reader:
        for connection, stamp, raw in reader.messages():
            topics[connection.topic].append(
                (stamp, store.deserialize_cdr(raw, connection.msgtype)))
    count = length + 1
    dt_ns = round(float(params.dt) * 1e6) * 1000
    scans = episode_scans(states, params, env.config.layout, count)
    assert len(topics["/map_markers"][0][1].markers[0].points) == 2 * len(spec.walls)
    odom = topics["/robot_1/odom"]
    in_world = np.asarray(states.robots.in_world[:count, 1])
    assert [t for t, _ in odom] == [k * dt_ns for k in np.flatnonzero(in_world)]
    for (stamp, message), k in zip(odom, np.flatnonzero(in_world), strict=True):
        assert message.header.stamp.sec * 10**9 + message.header.stamp.nanosec == stamp
        assert message.pose.pose.position.x == pytest.approx(float(states.robots.x[k, 1]),
                                                             abs=1e-6)
        assert message.twist.twist.linear.x == pytest.approx(
            float(states.robots.kin.v_forward[k, 1]), abs=1e-6)
    for (_, scan), k in zip(topics["/robot_1/scan"], np.flatnonzero(in_world), strict=True):
        np.testing.assert_allclose(scan.ranges, scans[k, 1], atol=1e-5)
    for k, (_, people) in enumerate(topics["/pedestrians"]):
        active = np.asarray(states.humans.active[k])
        xs = [p.position.x for p in people.poses]
        np.testing.assert_allclose(xs, np.asarray(states.humans.x[k])[active], atol=1e-6)
    for k, (_, decision) in enumerate(topics["/robots/decision"]):
        assert decision.data.tolist() == np.asarray(states.held_action[k]).tolist()
    assert [t for t, _ in topics["/robots/reward"]] == [k * dt_ns for k in range(1, count)]
    for k, (_, reward) in enumerate(topics["/robots/reward"]):
        np.testing.assert_allclose(reward.data, rewards[k], rtol=1e-6)


def test_a_live_view_serves_foxglove_clients_on_loopback(episode):
    """A WebSocket client speaking Foxglove's protocol sees the episode's channels advertised,
    subscribes to /step and receives its messages."""
    import struct
    import threading

    import websocket

    from sgjax.evaluation.episode_log import serve_episode

    env, params, states, length, rewards = episode
    spec = recorded_map("doorway", states)
    ports = []
    ready = threading.Event()
    served = []

    def started(port):
        ports.append(port)
        ready.set()

    thread = threading.Thread(target=lambda: served.append(serve_episode(
        spec, states, params, env.config.layout, length, port=0, speed=20.0,
        wait_for_client=20.0, started=started, rewards=rewards)), daemon=True)
    thread.start()
    assert ready.wait(20.0)
    client = websocket.create_connection(f"ws://127.0.0.1:{ports[0]}",
                                         subprotocols=["foxglove.sdk.v1"], timeout=20)
    channels = {}
    while "/step" not in channels:
        frame = client.recv()
        if isinstance(frame, str):
            message = json.loads(frame)
            if message["op"] == "advertise":
                channels.update({c["topic"]: c for c in message["channels"]})
    assert {"/map", "/robots", "/pedestrians", "/tf", "/robot_0/scan"} <= set(channels)
    client.send(json.dumps({"op": "subscribe", "subscriptions": [
        {"id": 7, "channelId": channels["/step"]["id"]}]}))
    steps = []
    while len(steps) < 3:
        frame = client.recv()
        if isinstance(frame, bytes) and frame[0] == 1:
            subscription, stamp = struct.unpack_from("<IQ", frame, 1)
            assert subscription == 7
            steps.append((stamp, json.loads(frame[13:])))
    client.close()
    thread.join(60.0)
    assert served == [length + 1]
    assert [s["decision"] for _, s in steps] == [
        np.asarray(states.held_action[round(stamp / 1e8)]).tolist() for stamp, _ in steps]
    for stamp, step in steps:
        if round(stamp / 1e8):
            np.testing.assert_allclose(step["reward"], rewards[round(stamp / 1e8) - 1],
                                       rtol=1e-6)


@pytest.mark.slow
def test_sgjax_evaluate_records_each_configurations_first_episode(tmp_path):
    main(["evaluate", "--scenario", "open", "--policy", "only_local", "random",
          "--num-agents", "2", "3", "--episodes", "3", "--time-limit", "5",
          "--out", str(tmp_path / "eval"), "--record-mcap", str(tmp_path / "mcap")])
    files = sorted(p.name for p in (tmp_path / "mcap").iterdir())
    assert files == ["open_only_local_2.mcap", "open_only_local_3.mcap", "open_random_2.mcap",
                     "open_random_3.mcap"]
    metrics = json.loads((tmp_path / "eval" / "metrics.json").read_text())
    first = read_back(tmp_path / "mcap" / "open_random_3.mcap")
    assert len(first["/tf"][0][1].transforms) == 3
    assert first["/metrics"][0][1]["episode_length"] == len(first["/tf"]) - 1
    rewarded = [step["reward"] for _, step in first["/step"]]
    assert rewarded[0] is None and all(len(r) == 3 for r in rewarded[1:])
    assert any(r["policy"] == "random" for r in metrics["results"])
