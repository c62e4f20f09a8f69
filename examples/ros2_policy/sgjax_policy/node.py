"""``python -m sgjax_policy.node --model actor.onnx --robots robot_0 robot_1``: an ``rclpy``
node that drives a fleet with an exported sgjax actor (:class:`.fleet.FleetController`).

Per robot ``NAME`` it subscribes to ``/NAME/odom`` (``nav_msgs/Odometry``), ``/NAME/goal``
(``geometry_msgs/PoseStamped``), ``/NAME/waypoint`` (``geometry_msgs/PointStamped``),
``/NAME/scan`` (``sensor_msgs/LaserScan``), ``/NAME/zone_ahead``
(``std_msgs/Float32MultiArray``) and ``/NAME/cmd_vel_planner`` (``geometry_msgs/Twist``, the
local planner's command that GO passes on), and publishes ``/NAME/cmd_vel``; people come on
``/people`` (``people_msgs/People``), an episode (task) starts on ``/episode_start``
(``std_msgs/Empty``). It ticks at the control period the actor was trained at.

Runs where ROS 2 is installed (``source /opt/ros/humble/setup.bash``; ``people_msgs`` from
the ``people`` package); elsewhere it says so and exits with status 2."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from .fleet import FleetController

MISSING_ROS = ("ROS 2 is not installed here (rclpy, or people_msgs, could not be imported: "
               "{error}). Source a ROS 2 installation (source /opt/ros/humble/setup.bash) and "
               "the people package, or use sgjax_policy.fleet.FleetController without ROS.")


def ros_modules() -> dict[str, Any]:
    """The ROS 2 modules the node needs (ImportError when ROS 2 is not installed)."""
    import rclpy
    from geometry_msgs.msg import PointStamped, PoseStamped, Twist
    from nav_msgs.msg import Odometry
    from people_msgs.msg import People
    from rclpy.node import Node
    from sensor_msgs.msg import LaserScan
    from std_msgs.msg import Empty, Float32MultiArray

    return dict(rclpy=rclpy, Node=Node, Odometry=Odometry, PoseStamped=PoseStamped,
                PointStamped=PointStamped, LaserScan=LaserScan, Twist=Twist, People=People,
                Float32MultiArray=Float32MultiArray, Empty=Empty)


def build_node(ros: dict[str, Any], fleet: FleetController) -> Any:
    """The node: subscriptions feeding ``fleet``, a publisher per robot, a timer."""
    node = ros["Node"]("sgjax_policy")
    publishers = {name: node.create_publisher(ros["Twist"], f"/{name}/cmd_vel", 10)
                  for name in fleet.names}
    topics = [("odom", "Odometry", fleet.on_odometry), ("goal", "PoseStamped", fleet.on_goal),
              ("waypoint", "PointStamped", fleet.on_waypoint),
              ("scan", "LaserScan", fleet.on_scan),
              ("zone_ahead", "Float32MultiArray", fleet.on_zone_ahead),
              ("cmd_vel_planner", "Twist", fleet.on_planner)]
    for name in fleet.names:
        for topic, kind, handler in topics:
            node.create_subscription(ros[kind], f"/{name}/{topic}",
                                     lambda msg, n=name, h=handler: h(n, msg), 10)
    node.create_subscription(ros["People"], "/people", fleet.on_people, 10)
    node.create_subscription(ros["Empty"], "/episode_start", lambda _: fleet.start(), 10)

    def tick() -> None:
        _, commands = fleet.tick()
        for name, (vx, vy, wz) in commands.items():
            twist = ros["Twist"]()
            twist.linear.x, twist.linear.y, twist.angular.z = vx, vy, wz
            publishers[name].publish(twist)

    node.create_timer(fleet.dt, tick)
    return node


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", required=True, help="the exported actor (.onnx; its "
                        ".json sidecar beside it)")
    parser.add_argument("--robots", nargs="+", required=True,
                        help="robot names (topic prefixes), in the actor's slot order")
    args = parser.parse_args(argv)
    try:
        ros = ros_modules()
    except ImportError as error:
        print(MISSING_ROS.format(error=error), file=sys.stderr)
        return 2
    fleet = FleetController(args.model, args.robots)
    ros["rclpy"].init()
    node = build_node(ros, fleet)
    try:
        ros["rclpy"].spin(node)
    finally:
        node.destroy_node()
        ros["rclpy"].shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
