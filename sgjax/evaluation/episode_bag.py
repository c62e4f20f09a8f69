"""One recorded episode as a ROS 2 bag of standard message types (``sgjax render --format
rosbag2``; issue 69), written with ``rosbags`` (no ROS install): ``ros2 bag play`` replays it to
RViz or any node.

The bag (rosbag2, SQLite storage, CDR) holds, on the simulation clock (step ``t`` at ``t * dt``
s, ``dt`` to the microsecond):

* ``/robot_i/odom`` (``nav_msgs/msg/Odometry``): pose in ``map`` and body velocity of robot
  ``i`` (``child_frame_id`` ``robot_i``), every step it is in the world;
* ``/robot_i/scan`` (``sensor_msgs/msg/LaserScan``): its lidar in frame ``robot_i``
  (:data:`sgjax.evaluation.episode_log.SCAN_BEAMS` beams over the full circle);
* ``/pedestrians`` (``geometry_msgs/msg/PoseArray``): the active pedestrians in ``map``;
* ``/robots/decision`` (``std_msgs/msg/Int8MultiArray``): each robot's GO (0) / STOP (1)
  decision (GO/STOP episodes only);
* ``/robots/reward`` (``std_msgs/msg/Float32MultiArray``, from the first step on, when the
  rewards were recorded): each robot's reward for the step that led to this time;
* ``/map_markers`` (``visualization_msgs/msg/MarkerArray``, once at 0 s): the walls as a
  line list."""

from __future__ import annotations

import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from sgjax.evaluation.episode_log import SCAN_RANGE, episode_frame
from sgjax.maps.schema import MapSpec

STORE = "ROS2_HUMBLE"  # the rosbags typestore of the message definitions


def _types() -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(getattr(Stores, STORE))


class _Messages:
    """Builders of the bag's messages from one typestore."""

    def __init__(self, store: Any):
        self.t = store.types
        self.store = store

    def header(self, nanos: int, frame: str) -> Any:
        time = self.t["builtin_interfaces/msg/Time"](sec=nanos // 10**9,
                                                       nanosec=nanos % 10**9)
        return self.t["std_msgs/msg/Header"](stamp=time, frame_id=frame)

    def vector(self, x: float, y: float, z: float = 0.0) -> Any:
        return self.t["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))

    def point(self, x: float, y: float, z: float = 0.0) -> Any:
        return self.t["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=float(z))

    def pose(self, x: float, y: float, heading: float = 0.0) -> Any:
        q = self.t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(heading / 2),
                                                    w=math.cos(heading / 2))
        return self.t["geometry_msgs/msg/Pose"](position=self.point(x, y), orientation=q)

    def odometry(self, nanos: int, robot: int, x: float, y: float, heading: float,
                 forward: float, lateral: float, turn: float) -> Any:
        t = self.t
        pose = t["geometry_msgs/msg/PoseWithCovariance"](
            pose=self.pose(x, y, heading), covariance=np.zeros(36, np.float64))
        twist = t["geometry_msgs/msg/TwistWithCovariance"](
            twist=t["geometry_msgs/msg/Twist"](linear=self.vector(forward, lateral),
                                                angular=self.vector(0.0, 0.0, turn)),
            covariance=np.zeros(36, np.float64))
        return t["nav_msgs/msg/Odometry"](header=self.header(nanos, "map"),
                                          child_frame_id=f"robot_{robot}", pose=pose,
                                          twist=twist)

    def scan(self, nanos: int, robot: int, ranges: np.ndarray, angles: np.ndarray,
             period: float) -> Any:
        return self.t["sensor_msgs/msg/LaserScan"](
            header=self.header(nanos, f"robot_{robot}"), angle_min=float(angles[0]),
            angle_max=float(angles[-1]), angle_increment=float(angles[1] - angles[0]),
            time_increment=0.0, scan_time=float(period), range_min=0.0,
            range_max=float(SCAN_RANGE), ranges=np.asarray(ranges, np.float32),
            intensities=np.zeros(0, np.float32))

    def poses(self, nanos: int, xs: np.ndarray, ys: np.ndarray) -> Any:
        return self.t["geometry_msgs/msg/PoseArray"](
            header=self.header(nanos, "map"), poses=[self.pose(x, y) for x, y in zip(
                xs, ys, strict=True)])

    def per_robot(self, values: np.ndarray, kind: str, dtype: Any) -> Any:
        """A ``std_msgs`` multi-array ``kind`` (``Int8MultiArray``, ``Float32MultiArray``) of
        one value per robot."""
        t = self.t
        layout = t["std_msgs/msg/MultiArrayLayout"](dim=[t["std_msgs/msg/MultiArrayDimension"](
            label="robot", size=int(values.size), stride=int(values.size))], data_offset=0)
        return t[f"std_msgs/msg/{kind}"](layout=layout, data=np.asarray(values, dtype))

    def walls(self, spec: MapSpec) -> Any:
        t = self.t
        marker = t["visualization_msgs/msg/Marker"]
        points = [self.point(w[a], w[a + 1]) for w in spec.walls for a in (0, 2)]
        wall = marker(
            header=self.header(0, "map"), ns="walls", id=0, type=marker.LINE_LIST,
            action=marker.ADD, pose=self.pose(0.0, 0.0), scale=self.vector(0.05, 0.0, 0.0),
            color=t["std_msgs/msg/ColorRGBA"](r=0.1, g=0.1, b=0.1, a=1.0),
            lifetime=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),
            frame_locked=False, points=points, colors=[], texture_resource="",
            texture=t["sensor_msgs/msg/CompressedImage"](
                header=self.header(0, ""), format="", data=np.zeros(0, np.uint8)),
            uv_coordinates=[], text="", mesh_resource="",
            mesh_file=t["visualization_msgs/msg/MeshFile"](filename="",
                                                          data=np.zeros(0, np.uint8)),
            mesh_use_embedded_materials=False)
        return t["visualization_msgs/msg/MarkerArray"](markers=[wall])


def write_rosbag2(path: str | Path, spec: MapSpec, states: Any, params: Any, layout: Any,
                  length: int, rewards: np.ndarray | None = None) -> Path:
    """Write one recorded episode (``states`` stacked ``[T + 1, ...]`` of one environment,
    the first ``length + 1`` written; ``rewards [T, R]`` its steps' rewards, if known) as the
    rosbag2 folder ``path`` (module doc; an existing folder is replaced). Returns the path."""
    from rosbags.rosbag2 import Writer

    path = Path(path)
    if path.exists():
        shutil.rmtree(path)
    store = _types()
    make = _Messages(store)
    count, step_ns, scans, angles, held = episode_frame(states, params, layout, length)
    robots = int(np.shape(states.robots.x)[1])
    r, h = states.robots, states.humans
    in_world = np.asarray(r.in_world[:count])
    x, y, heading = (np.asarray(v[:count]) for v in (r.x, r.y, r.kin.heading))
    forward, lateral = np.asarray(r.kin.v_forward[:count]), np.asarray(r.kin.v_lateral[:count])
    turn = np.asarray(r.kin.omega[:count])
    hx, hy, ha = (np.asarray(v[:count]) for v in (h.x, h.y, h.active))
    with Writer(path, version=8) as writer:
        def topic(name: str, kind: str) -> Any:
            return writer.add_connection(name, kind, typestore=store)

        odom = [topic(f"/robot_{i}/odom", "nav_msgs/msg/Odometry") for i in range(robots)]
        scan = [topic(f"/robot_{i}/scan", "sensor_msgs/msg/LaserScan") for i in range(robots)]
        people = topic("/pedestrians", "geometry_msgs/msg/PoseArray")
        decision = topic("/robots/decision", "std_msgs/msg/Int8MultiArray") \
            if held.ndim == 2 else None
        walls = topic("/map_markers", "visualization_msgs/msg/MarkerArray")
        reward = topic("/robots/reward", "std_msgs/msg/Float32MultiArray") \
            if rewards is not None else None

        def put(connection: Any, nanos: int, message: Any, kind: str) -> None:
            writer.write(connection, nanos, store.serialize_cdr(message, kind))

        put(walls, 0, make.walls(spec), "visualization_msgs/msg/MarkerArray")
        for t in range(count):
            nanos = t * step_ns
            for i in np.flatnonzero(in_world[t]):
                put(odom[i], nanos, make.odometry(nanos, int(i), x[t, i], y[t, i],
                                                  heading[t, i], forward[t, i],
                                                  lateral[t, i], turn[t, i]),
                    "nav_msgs/msg/Odometry")
                put(scan[i], nanos, make.scan(nanos, int(i), scans[t, i], angles,
                                              step_ns / 1e9), "sensor_msgs/msg/LaserScan")
            put(people, nanos, make.poses(nanos, hx[t][ha[t]], hy[t][ha[t]]),
                "geometry_msgs/msg/PoseArray")
            if decision is not None:
                put(decision, nanos, make.per_robot(held[t], "Int8MultiArray", np.int8),
                    "std_msgs/msg/Int8MultiArray")
            if reward is not None and t > 0:
                put(reward, nanos, make.per_robot(rewards[t - 1], "Float32MultiArray",
                                                  np.float32), "std_msgs/msg/Float32MultiArray")
    return path
