"""What the bridge publishes and subscribes: topic names, frames, rates and QoS, as dataclasses."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from ..utils.validate import Checked, rule

QosName = Literal["default", "sensor_data"]
"""``default``: reliable, volatile, keep-last 10 (rclpy's default and Isaac Sim's); ``sensor_data``:
best-effort, keep-last 5 (``rclpy.qos.qos_profile_sensor_data``) for cameras on lossy links."""


@dataclass(kw_only=True)
class BridgeCfg(Checked):
    """The ROS 2 face of a World. Rates are Hz of *simulated* time (``None``: every physics step);
    topic names are relative to ``namespace`` unless they start with ``/``."""

    node_name: str = "ambulo_bridge"
    namespace: str = ""
    """ROS namespace of the node and of relative topic names (``/robot1``)."""
    clock_topic: str = "/clock"
    joint_states_topic: str = "joint_states"
    imu_topic: str = "imu/data"
    odom_topic: str = "odom"
    robot_description_topic: str = "robot_description"
    """std_msgs/String URDF of the robots (transient-local), for rviz2's RobotModel display."""
    scan_topic: str = "scan"
    points_topic: str = "points"
    cmd_vel_topic: str = "cmd_vel"
    joint_command_topic: str = "joint_group_position_controller/command"
    """std_msgs/Float64MultiArray: position targets for ``command_joints`` (all joints by default)."""
    joint_state_command_topic: str = "joint_command"
    """sensor_msgs/JointState by joint name (Isaac Sim's "ROS2 Subscribe Joint State" topic)."""
    camera_namespace: str = "camera"
    """Camera topics are ``<camera_namespace>/<camera name>/{image_raw,depth,camera_info}``; with one
    camera ``<camera_namespace>/{image_raw,depth,camera_info}``."""

    clock_rate_hz: float | None = None
    joint_states_rate_hz: float | None = None
    imu_rate_hz: float | None = None
    tf_rate_hz: float | None = None
    odom_rate_hz: float | None = None
    camera_rate_hz: float = 10.0
    lidar_rate_hz: float = 10.0

    odom_frame: str = "odom"
    """The fixed frame: the simulator's world (ground truth odometry, no drift)."""
    base_frame: str = "base_link"
    """Frame of each robot's root body; other links keep their body names."""
    frame_prefix: str = ""
    """Put before every frame id (``robot1/``); with several robots each also gets ``<name>/``."""

    camera_qos: QosName = "default"
    fastdds_profile: bool = True
    """Give the bridge's Fast DDS participant 16 MB shared-memory segments and 4 MB UDP buffers (images
    arrive in ~2 ms instead of ~12 ms on loopback); skipped when the user set a Fast DDS profile."""
    data_qos_depth: int = 10
    publish_depth: bool = True
    robot: str | None = None
    """Scene name of the robot that odometry, /cmd_vel and joint commands refer to (None: the first)."""
    command_joints: list[str] | None = None
    """Joints, in order, that ``joint_command_topic`` arrays address (None: all of ``robot``'s)."""
    max_linear_speed_m_s: float = 0.8
    """|v| above this is rejected (for a /cmd_vel handler without limits of its own: the humanoid's walking
    policy has its trained ranges instead, linear.x [-1, 1], linear.y [-0.5, 0.5] m/s, angular.z [-1, 1]
    rad/s): the Jetbot's TT gearmotors (1:48, ~250 rpm at 6 V) on 30 mm wheels
    give 250 / 60 * 2 pi * 0.03 = 0.79 m/s."""
    max_angular_speed_rad_s: float = 14.0
    """|yaw rate| above this is rejected: both wheels at 0.79 m/s in opposite senses on the Jetbot's
    0.1125 m wheel base, 2 * 0.79 / 0.1125 = 14 rad/s."""
    record: str | None = None
    """Write every published message to this rosbag2 folder (MCAP storage) while the bridge runs."""
    foxglove_port: int | None = None
    """Also serve every topic over Foxglove's WebSocket protocol on 127.0.0.1:port (``foxglove-sdk``)."""
    snapshot_slots: int = 256
    """Snapshots of the physics state that may wait for the publisher process (a ring in shared memory)."""
    publisher_nice: int = field(default=5, metadata=rule(signed=True))
    """Niceness added to the publisher process (``os.nice``; 0: none). When every core is busy (other
    programs, or a subscriber on the same cores) the physics loop gets the CPU first (about 3:1 at 5),
    and messages, discovery and commands wait instead; with a core to spare it changes nothing."""
    publisher_cpus: Literal["auto"] | list[int] | None = "auto"
    """CPUs the publisher process may run on (``os.sched_setaffinity``). ``auto``: every CPU this process
    may use except the one the bridge was created on (the physics thread's), when there are at least
    two, so publishing never evicts the physics loop's caches on its core nor preempts it there;
    the physics thread itself is not pinned. None: no restriction."""
    drop_when_behind: bool = False
    """When the ring is full (the simulation outruns the publisher process, e.g. stepping flat out with
    topics every step): False waits for a free slot, so every message goes out and the bag is complete;
    True skips the snapshot (counted in ``Ros2Bridge.dropped``), so the physics loop never waits."""
    detector_thread: bool = True
    """With a detector (``Ros2Bridge(..., detector=)``): True runs it on a thread of its own, so the simulation
    keeps its pace while it works; a camera frame arriving while it is busy replaces the one waiting (counted in
    ``Ros2Bridge.dropped_detections``) and detections carry their frame's stamp. False runs it in the camera
    path on the physics thread: every published frame detected, deterministic (tests, offline evaluation)."""


__all__ = ["BridgeCfg", "QosName"]
