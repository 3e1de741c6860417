"""Isaac Sim's ROS 2 driving tutorial on ambulo: a Jetbot World becomes a ROS 2 node, and a plain
rclpy node (a stand-in for ``ros2 topic pub /cmd_vel`` or Nav2) drives it and reads /odom.

    python examples/ros2/jetbot_teleop.py [--seconds 2] [--speed 0.3] [--record out.mcap]

Needs ``pip install 'ambulo[ros2]'``. While it runs, any ROS 2 machine on the same
``ROS_DOMAIN_ID`` sees /joint_states, /tf, /odom, /imu/data and the camera topics.
"""

from __future__ import annotations

import argparse
import json
import math
import time

from ambulo import assets
from ambulo.ros2 import BridgeCfg, Ros2Bridge
from ambulo.sensors import Imu, ImuCfg
from ambulo.sim import WheeledRobot, World


def teleop_node(speed_m_s: float):
    """An ordinary rclpy node: publishes a Twist, remembers the last /odom pose."""
    import rclpy
    from geometry_msgs.msg import Twist
    from nav_msgs.msg import Odometry

    node = rclpy.create_node("teleop")
    pub = node.create_publisher(Twist, "/cmd_vel", 10)
    odom: list = []
    node.create_subscription(Odometry, "/odom", lambda m: odom.append((m.pose.pose.position.x,
                                                                      m.pose.pose.position.y)), 200)
    command = Twist()
    command.linear.x = speed_m_s
    return node, pub, command, odom


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=2.0, help="simulated seconds of driving")
    parser.add_argument("--speed", type=float, default=0.3, help="m/s sent on /cmd_vel")
    parser.add_argument("--record", help="rosbag2 folder to record into")
    args = parser.parse_args(argv)

    world = World(physics_dt=0.01)
    world.scene.add_default_ground_plane()
    jetbot = world.scene.add(WheeledRobot(prim_path="/World/Jetbot", name="jetbot", create_robot=True,
                                          usd_path=assets.path("jetbot"),
                                          wheel_dof_names=["left_wheel_joint", "right_wheel_joint"]))
    world.scene.add(Imu(ImuCfg(prim_path="/World/Jetbot/chassis/imu")))
    world.reset()
    bridge = Ros2Bridge(world, BridgeCfg(record=args.record))

    import rclpy

    rclpy.init()  # the teleop node's own ROS context (the bridge has another)
    node, pub, command, odom = teleop_node(args.speed)
    try:
        # Until discovery has matched both ways: the bridge holds the command AND an /odom came
        # back. Each direction is discovered on its own; on a busy machine /odom can match seconds
        # after /cmd_vel, and what is published before that is gone (volatile, keep-last 10).
        deadline = time.monotonic() + 120.0
        while bridge.cmd_vel is None or not odom:
            if time.monotonic() > deadline:
                raise SystemExit("teleop: no ROS 2 discovery between the bridge and this node in 120 s; "
                                 "check ROS_DOMAIN_ID and that multicast works on loopback")
            pub.publish(command)
            rclpy.spin_once(node, timeout_sec=0.01)
            world.step(render=False)
        odom.clear()  # count only what the driving below publishes
        start = jetbot.get_world_pose()[0]
        for _ in range(int(round(args.seconds / world.get_physics_dt()))):
            world.step(render=False)
            rclpy.spin_once(node, timeout_sec=0)
        end = jetbot.get_world_pose()[0]
        idle, seen = 0, -1
        while idle < 20:  # take what is queued or in flight until 0.2 s pass without an /odom
            rclpy.spin_once(node, timeout_sec=0.01)
            idle, seen = (idle + 1, seen) if len(odom) == seen else (0, len(odom))
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        bridge.close()
    driven = float(math.dist(start[:2], end[:2]))
    result = {"driven_m": driven, "expected_m": args.speed * args.seconds, "odom_messages": len(odom),
              "odom_last_xy": list(odom[-1]) if odom else None, "sim_xy": [float(end[0]), float(end[1])],
              "published": dict(bridge.published)}
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main()
