"""One recorded episode as an MCAP file in Foxglove's schemas (``sgjax render --format mcap``;
issue 69): Foxglove's 3D panel shows it without configuration.

One file per episode (the episodes of a batch share their clock, so one file of many would lay
them over each other on one timeline). Time stamps follow the simulation clock: step ``t`` at
``t * dt`` s from 0 (``dt`` to the microsecond). Topics (Foxglove's protobuf schemas, written
by foxglove-sdk's MCAP writer, each file its own :class:`foxglove.Context` so that nothing
else logged in the process reaches it):

* ``/map`` (``foxglove.SceneUpdate``, once at 0 s): the walls (a line list, 5 cm thick), the
  navigation graph (thin grey lines), the conflict zones (flat translucent boxes);
* ``/robots`` (``SceneUpdate``, every step): each robot in the world as a cylinder of its
  footprint (green while GO, red while STOP, grey once finished), an arrow along its heading,
  its goal (a small cylinder) and the rest of its route (a line strip);
* ``/pedestrians`` (``SceneUpdate``, every step): each active pedestrian as a cylinder;
* ``/tf`` (``foxglove.FrameTransforms``, every step): ``map`` -> ``robot_i``, the robots' poses;
* ``/robot_i/scan`` (``foxglove.LaserScan``, every step): a 2D lidar from the robot's centre
  (:data:`SCAN_BEAMS` beams over the full circle, :data:`SCAN_RANGE` m: walls, robots,
  pedestrians), in the robot's frame;
* ``/step`` (JSON, every step): the time (s), and per robot its reward for the step that
  led here (null at 0 s, or when not recorded), its GO/STOP decision (or continuous action),
  whether it is active and its goal distance (m);
* ``/metrics`` (JSON, at the episode's end): the episode's metrics.

Reading a file back: ``mcap``'s reader with ``mcap_protobuf``'s decoder (the tests do)."""

from __future__ import annotations

import json
import math
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import jax
import numpy as np

from sgjax.maps.schema import MapSpec
from sgjax.observations.lidar import Lidar, beam_angles
from sgjax.terms.contract import TermInput
from sgjax.types import GO

SCAN_BEAMS = 64  # lidar beams per robot in a logged episode
SCAN_RANGE = 10.0  # m
ROBOT_HEIGHT = 0.4  # m: the robots' cylinders (drawing only)
HUMAN_HEIGHT = 1.7  # m: the pedestrians' cylinders


def episode_scans(states: Any, params: Any, layout: Any, count: int) -> np.ndarray:
    """``[count, R, SCAN_BEAMS]`` (m): every robot's lidar at each of the first ``count``
    recorded states (``states`` stacked ``[T, ...]`` of one environment)."""
    lidar = Lidar(beams=SCAN_BEAMS, range=SCAN_RANGE)
    first = jax.tree.map(lambda leaf: leaf[:count], states)

    def one(state: Any) -> jax.Array:
        return lidar(TermInput.observing(state, params, layout, jax.random.key(0)))

    return np.asarray(jax.jit(jax.vmap(one))(first))


def episode_frame(states: Any, params: Any, layout: Any, length: int
                  ) -> tuple[int, int, np.ndarray, np.ndarray, np.ndarray]:
    """What every episode file needs of a recorded episode (``states [T + 1, ...]``, its
    first ``length + 1`` written): ``(count, ns per step, scans [count, R, beams] (m), beam
    angles [beams] (rad), held actions [count, R(, A)])``; the step's ns are ``dt`` rounded
    to the microsecond (float32's 0.1 s is 0.100000001 s)."""
    count = min(length + 1, int(np.shape(states.time)[0]))
    step_ns = int(round(float(np.asarray(params.dt)) * 1e6)) * 1000
    scans = episode_scans(states, params, layout, count)
    angles = np.asarray(beam_angles(SCAN_BEAMS, 2.0 * math.pi))
    return count, step_ns, scans, angles, np.asarray(states.held_action[:count])


def _stamp(seconds: float) -> Any:
    from foxglove.messages import Timestamp

    whole = math.floor(seconds)
    return Timestamp(sec=int(whole), nsec=int(round((seconds - whole) * 1e9)))


def _pose(x: float, y: float, heading: float = 0.0, z: float = 0.0) -> Any:
    from foxglove.messages import Pose, Quaternion, Vector3

    return Pose(position=Vector3(x=float(x), y=float(y), z=float(z)),
                orientation=Quaternion(x=0.0, y=0.0, z=math.sin(heading / 2.0),
                                       w=math.cos(heading / 2.0)))


def _color(r: float, g: float, b: float, a: float = 1.0) -> Any:
    from foxglove.messages import Color

    return Color(r=r, g=g, b=b, a=a)


def _points(pairs: Any) -> list[Any]:
    from foxglove.messages import Point3

    return [Point3(x=float(x), y=float(y), z=0.0) for x, y in pairs]


def map_scene(spec: MapSpec) -> Any:
    """The ``/map`` scene of ``spec``: walls, graph and zones as three entities."""
    from foxglove.messages import (
        CubePrimitive,
        LinePrimitive,
        LinePrimitiveLineType,
        SceneEntity,
        SceneUpdate,
        Vector3,
    )

    lines = LinePrimitiveLineType.LineList
    walls = [p for w in spec.walls for p in ((w[0], w[1]), (w[2], w[3]))]
    nodes = spec.node_positions
    edges = [p for a, b in spec.edges for p in (nodes[a], nodes[b])]
    zones = [CubePrimitive(pose=_pose((z.rect[0] + z.rect[2]) / 2, (z.rect[1] + z.rect[3]) / 2,
                                      z=0.005),
                           size=Vector3(x=z.rect[2] - z.rect[0], y=z.rect[3] - z.rect[1],
                                        z=0.01),
                           color=_color(1.0, 0.8, 0.2, 0.25)) for z in spec.zones]
    stamp = _stamp(0.0)
    return SceneUpdate(entities=[
        SceneEntity(timestamp=stamp, frame_id="map", id="walls", lines=[LinePrimitive(
            type=lines, pose=_pose(0, 0), thickness=0.05, points=_points(walls),
            color=_color(0.1, 0.1, 0.1))] if walls else []),
        SceneEntity(timestamp=stamp, frame_id="map", id="graph", lines=[LinePrimitive(
            type=lines, pose=_pose(0, 0), thickness=0.01, points=_points(edges),
            color=_color(0.6, 0.65, 0.75, 0.5))] if edges else []),
        SceneEntity(timestamp=stamp, frame_id="map", id="zones", cubes=zones),
    ])


def _robot_entities(t: int, seconds: float, states: Any, params: Any, decision: np.ndarray,
                    discrete: bool) -> list[Any]:
    from foxglove.messages import (
        ArrowPrimitive,
        CylinderPrimitive,
        LinePrimitive,
        LinePrimitiveLineType,
        SceneEntity,
        Vector3,
    )

    r = states.robots
    x, y = np.asarray(r.x[t]), np.asarray(r.y[t])
    heading = np.asarray(r.kin.heading[t])
    in_world, active = np.asarray(r.in_world[t]), np.asarray(r.active[t])
    radius = np.asarray(params.robots.radius)
    route_x, route_y = np.asarray(states.route.x[t]), np.asarray(states.route.y[t])
    stamp = _stamp(seconds)
    out = []
    for i in np.flatnonzero(in_world):
        going = (decision[i] == GO) if discrete else True
        color = (_color(0.2, 0.7, 0.3) if going else _color(0.85, 0.2, 0.2)) if active[i] \
            else _color(0.55, 0.55, 0.55)
        size = 2.0 * float(radius[i])
        out.append(SceneEntity(
            timestamp=stamp, frame_id="map", id=f"robot_{i}",
            cylinders=[CylinderPrimitive(pose=_pose(x[i], y[i], z=ROBOT_HEIGHT / 2),
                                         size=Vector3(x=size, y=size, z=ROBOT_HEIGHT),
                                         bottom_scale=1.0, top_scale=1.0, color=color),
                       CylinderPrimitive(pose=_pose(route_x[i, -1], route_y[i, -1], z=0.01),
                                         size=Vector3(x=0.3, y=0.3, z=0.02), bottom_scale=1.0,
                                         top_scale=1.0, color=_color(0.2, 0.4, 0.9, 0.6))],
            arrows=[ArrowPrimitive(pose=_pose(x[i], y[i], heading[i], ROBOT_HEIGHT + 0.05),
                                   shaft_length=size, shaft_diameter=0.05, head_length=0.15,
                                   head_diameter=0.12, color=_color(0.1, 0.1, 0.1))],
            lines=[LinePrimitive(type=LinePrimitiveLineType.LineStrip, pose=_pose(0, 0),
                                 thickness=0.03, points=_points(
                                     [(x[i], y[i]), *zip(route_x[i], route_y[i], strict=True)]),
                                 color=_color(0.2, 0.4, 0.9, 0.5))] if active[i] else []))
    return out


def _people_entities(t: int, seconds: float, states: Any, params: Any) -> list[Any]:
    from foxglove.messages import CylinderPrimitive, SceneEntity, Vector3

    h = states.humans
    active = np.asarray(h.active[t])
    if not active.size:
        return []
    x, y = np.asarray(h.x[t]), np.asarray(h.y[t])
    size = 2.0 * float(np.asarray(params.humans.radius))
    stamp = _stamp(seconds)
    return [SceneEntity(timestamp=stamp, frame_id="map", id=f"pedestrian_{k}",
                        cylinders=[CylinderPrimitive(
                            pose=_pose(x[k], y[k], z=HUMAN_HEIGHT / 2),
                            size=Vector3(x=size, y=size, z=HUMAN_HEIGHT), bottom_scale=1.0,
                            top_scale=1.0, color=_color(0.45, 0.45, 0.5, 0.9))])
            for k in np.flatnonzero(active)]


def log_episode(context: Any, spec: MapSpec, states: Any, params: Any, layout: Any,
                length: int, rewards: np.ndarray | None = None,
                metrics: Mapping[str, Any] | None = None,
                pace: Callable[[int], None] | None = None) -> int:
    """Log one recorded episode (``states`` stacked ``[T + 1, ...]`` of one environment, the
    first ``length + 1`` logged; ``rewards [T, R]`` of its steps when known; ``metrics`` its
    final values) on the module doc's topics of the :class:`foxglove.Context` ``context``,
    whatever its sinks (an MCAP file, a WebSocket server). ``pace(t)`` runs before step ``t``
    is logged (a live view waits there). Returns the steps logged."""
    import foxglove
    from foxglove.channels import FrameTransformsChannel, LaserScanChannel, SceneUpdateChannel
    from foxglove.messages import (
        FrameTransform,
        FrameTransforms,
        LaserScan,
        Quaternion,
        SceneUpdate,
        Vector3,
    )

    count, step_ns, scans, angles, held = episode_frame(states, params, layout, length)
    robots = int(np.shape(states.robots.x)[1])
    discrete = held.ndim == 2
    scene_map = SceneUpdateChannel("/map", context=context)
    scene_robots = SceneUpdateChannel("/robots", context=context)
    scene_people = SceneUpdateChannel("/pedestrians", context=context)
    tf = FrameTransformsChannel("/tf", context=context)
    lidar = [LaserScanChannel(f"/robot_{i}/scan", context=context) for i in range(robots)]
    step_channel = foxglove.Channel("/step", message_encoding="json", context=context)
    goal = np.asarray(states.route.x[:count, :, -1]), np.asarray(states.route.y[:count, :, -1])
    for t in range(count):
        if pace is not None:
            pace(t)
        if t == 0:  # after the first pace: a live client has subscribed by then
            scene_map.log(map_scene(spec), log_time=0)
        nanos = t * step_ns
        seconds = nanos / 1e9
        scene_robots.log(SceneUpdate(entities=_robot_entities(
            t, seconds, states, params, held[t], discrete)), log_time=nanos)
        scene_people.log(SceneUpdate(entities=_people_entities(t, seconds, states, params)),
                         log_time=nanos)
        r = states.robots
        x, y = np.asarray(r.x[t]), np.asarray(r.y[t])
        heading = np.asarray(r.kin.heading[t])
        stamp = _stamp(seconds)
        tf.log(FrameTransforms(transforms=[FrameTransform(
            timestamp=stamp, parent_frame_id="map", child_frame_id=f"robot_{i}",
            translation=Vector3(x=float(x[i]), y=float(y[i]), z=0.0),
            rotation=Quaternion(x=0.0, y=0.0, z=math.sin(heading[i] / 2),
                                w=math.cos(heading[i] / 2))) for i in range(robots)]),
            log_time=nanos)
        for i in range(robots):
            lidar[i].log(LaserScan(timestamp=stamp, frame_id=f"robot_{i}", pose=_pose(0, 0),
                                   start_angle=float(angles[0]), end_angle=float(angles[-1]),
                                   ranges=[float(v) for v in scans[t, i]]), log_time=nanos)
        step_channel.log({
            "time": seconds,
            "reward": (None if rewards is None or t == 0
                       else [float(v) for v in rewards[t - 1]]),
            "decision": held[t].tolist(),
            "active": np.asarray(r.active[t]).tolist(),
            "goal_distance": np.hypot(goal[0][t] - x, goal[1][t] - y).round(4).tolist(),
        }, log_time=nanos)
    if metrics is not None:
        end = foxglove.Channel("/metrics", message_encoding="json", context=context)
        end.log(json.loads(json.dumps(dict(metrics), default=float)),
                log_time=(count - 1) * step_ns)
    return count


def write_mcap(path: str | Path, spec: MapSpec, states: Any, params: Any, layout: Any,
               length: int, rewards: np.ndarray | None = None,
               metrics: Mapping[str, Any] | None = None) -> Path:
    """Write one recorded episode as the MCAP file ``path`` (:func:`log_episode`'s topics,
    in a context of its own). Returns the path."""
    import foxglove

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    context = foxglove.Context()
    writer = foxglove.open_mcap(str(path), allow_overwrite=True, context=context)
    try:
        log_episode(context, spec, states, params, layout, length, rewards, metrics)
    finally:
        writer.close()
    return path


def serve_episode(spec: MapSpec, states: Any, params: Any, layout: Any, length: int,
                  host: str = "127.0.0.1", port: int = 8765, speed: float = 1.0,
                  wait_for_client: float = 0.0, metrics: Mapping[str, Any] | None = None,
                  started: Callable[[int], None] | None = None,
                  rewards: np.ndarray | None = None) -> int:
    """Serve one recorded episode live to Foxglove over its WebSocket protocol (foxglove-sdk's
    server, subprotocol ``foxglove.sdk.v1``, bound to ``host``: loopback unless told
    otherwise), step by step at ``speed`` times the simulation clock, once a client has
    subscribed to one of its channels (or ``wait_for_client`` s have passed).
    ``started(port)`` runs once the server listens (``port`` 0 picks a free one). Returns the
    steps served."""
    import foxglove

    context = foxglove.Context()
    subscribed = threading.Event()

    class Listener(foxglove.ServerListener):
        def on_subscribe(self, client: Any, channel: Any) -> None:
            subscribed.set()

    server = foxglove.start_server(name="sgjax", host=host, port=port, context=context,
                                   server_listener=Listener())
    try:
        if started is not None:
            started(server.port)
        step_s = float(np.asarray(params.dt)) / max(speed, 1e-9)
        clock = [0.0]

        def pace(t: int) -> None:
            if t == 0:  # the channels are advertised now: wait for a subscriber
                subscribed.wait(wait_for_client)
                clock[0] = time.perf_counter()
            delay = clock[0] + t * step_s - time.perf_counter()
            if delay > 0:
                time.sleep(delay)

        return log_episode(context, spec, states, params, layout, length, rewards=rewards,
                           metrics=metrics, pace=pace)
    finally:
        server.stop()
