"""ROS 2 bridge: a World as a real ROS 2 node (rclpy), rosbag2 recording, wheel-less message types.

``Ros2Bridge(world, BridgeCfg(...))`` publishes /clock, /joint_states, /imu/data, /tf, /tf_static,
/odom, camera image_raw/depth/camera_info and lidar /scan or /points, stamped with simulated time,
and takes /cmd_vel, /joint_group_position_controller/command and /joint_command. Needs
``pip install 'ambulo[ros2]'`` (or a sourced ROS 2); rclpy is imported only when a bridge starts.
"""

from .config import BridgeCfg
from .scenes import SCENES, SceneCfg, file_world, humanoid_world, jetbot_world


def __getattr__(name: str):
    if name in ("Ros2Bridge", "attach_bridge"):
        from . import bridge  # imports rclpy

        return getattr(bridge, name)
    raise AttributeError(f"module 'ambulo.ros2' has no attribute {name!r}")


__all__ = ["SCENES", "BridgeCfg", "Ros2Bridge", "SceneCfg", "attach_bridge", "file_world", "humanoid_world",
           "jetbot_world"]
