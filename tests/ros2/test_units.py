"""The bridge's parts without a network: type hashes, command checks, message conversions."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")

from ambulo.ros2.commands import names_problem, range_problem, targets_problem, twist_problem
from ambulo.ros2.raw_types import hash_of, type_description, typestore

TYPES = ["tf2_msgs/msg/TFMessage", "sensor_msgs/msg/JointState", "sensor_msgs/msg/Imu", "sensor_msgs/msg/Image",
         "sensor_msgs/msg/CameraInfo", "sensor_msgs/msg/LaserScan", "sensor_msgs/msg/PointCloud2",
         "nav_msgs/msg/Odometry", "rosgraph_msgs/msg/Clock", "geometry_msgs/msg/Twist",
         "std_msgs/msg/Float64MultiArray"]


@pytest.mark.parametrize("typename", TYPES)
def test_type_hash_equals_rosbags(typename):
    assert hash_of(typename) == typestore().hash_rihs01(typename)


def test_type_hash_equals_what_rosidl_generated_for_the_wheels():
    """rosidl's own output, shipped with the geometry_msgs wheel (share/<pkg>/msg/<Name>.json)."""
    shipped = Path(sys.prefix) / "share" / "geometry_msgs" / "msg" / "TransformStamped.json"
    if not shipped.exists():
        pytest.skip("needs the ros-geometry-msgs wheel")
    hashes = {h["type_name"]: h["hash_string"] for h in json.loads(shipped.read_text())["type_hashes"]}
    for typename, expected in hashes.items():
        assert hash_of(typename) == expected


def test_tf_message_description_nests_transform_stamped():
    desc = type_description("tf2_msgs/msg/TFMessage")
    (field,) = desc["type_description"]["fields"]
    assert field["name"] == "transforms"
    assert field["type"] == {"type_id": 145, "capacity": 0, "string_capacity": 0,  # unbounded nested sequence
                             "nested_type_name": "geometry_msgs/msg/TransformStamped"}
    names = [d["type_name"] for d in desc["referenced_type_descriptions"]]
    assert names == sorted(names) and "geometry_msgs/msg/TransformStamped" in names


@pytest.mark.parametrize("linear, angular, holonomic, problem", [
    ((0.3, 0, 0), (0, 0, 0.5), False, None),
    ((math.nan, 0, 0), (0, 0, 0), False, "linear.x is nan"),
    ((0, 0, 0), (0, 0, -math.inf), False, "angular.z is -inf"),
    ((0.1, 0.2, 0), (0, 0, 0), False, "linear.y=0.2 but this robot drives in the plane and cannot move sideways"),
    ((0.1, 0.2, 0), (0, 0, 0), True, None),
    ((0, 0, 0.1), (0, 0, 0), True, "linear.z=0.1"),
    ((0, 0, 0), (0.3, 0, 0), False, "angular.x=0.3"),
    ((1.5, 0, 0), (0, 0, 0), False, "linear speed 1.5 m/s exceeds the robot's limit of 1 m/s"),
    ((0.8, 0.8, 0), (0, 0, 0), True, "exceeds the robot's limit"),
    ((0, 0, 0), (0, 0, 7), False, "angular.z 7 rad/s exceeds"),
])
def test_twist_checks(linear, angular, holonomic, problem):
    found = twist_problem(linear, angular, 1.0, 6.0, holonomic)
    if problem is None:
        assert found is None
    else:
        assert problem in found


WALK_RANGES = {"linear.x": (-1.0, 1.0), "linear.y": (-0.5, 0.5), "angular.z": (-1.0, 1.0)}


@pytest.mark.parametrize("linear, angular, problem", [
    ((1.0, -0.5, 0), (0, 0, -1.0), None),  # the edges of the trained ranges are accepted
    ((1.01, 0, 0), (0, 0, 0), "linear.x 1.01 m/s exceeds the walking policy's trained range of [-1, 1] m/s"),
    ((0, 0.6, 0), (0, 0, 0), "linear.y 0.6 m/s exceeds the walking policy's trained range of [-0.5, 0.5] m/s"),
    ((0, 0, 0), (0, 0, -1.5), "angular.z -1.5 rad/s exceeds the walking policy's trained range of [-1, 1] rad/s"),
    ((math.nan, 0, 0), (0, 0, 0), "linear.x is nan"),
    ((0, 0, 0), (0, 0, math.inf), "angular.z is inf"),
    ((0, 0, 0.2), (0, 0, 0), "linear.z=0.2 but this robot moves in the plane"),
])
def test_walking_twist_checks(linear, angular, problem):
    found = range_problem(linear, angular, WALK_RANGES, "the walking policy's trained range")
    if problem is None:
        assert found is None
    else:
        assert problem in found


def test_humanoid_cmd_vel_gets_the_walking_policy_only_at_its_physics_dt():
    from ambulo.policies.shipped import load_policy
    from ambulo.robots.humanoid import POLICY_PHYSICS_DT_S
    from ambulo.ros2 import SceneCfg, humanoid_world
    from ambulo.ros2.commands import NoWalkingPolicy, WalkingPolicyDrive, default_cmd_vel_handler

    contract = load_policy("humanoid-walk").contract
    assert POLICY_PHYSICS_DT_S == contract["physics_dt_s"]
    world = humanoid_world(SceneCfg(camera=False))
    assert world.get_physics_dt() == POLICY_PHYSICS_DT_S
    robot = world.scene.get_object("humanoid")
    handler = default_cmd_vel_handler(robot, world.get_physics_dt())
    assert isinstance(handler, WalkingPolicyDrive)
    assert handler.ranges == {"linear.x": (-1.0, 1.0), "linear.y": (-0.5, 0.5), "angular.z": (-1.0, 1.0)}
    # initialize() stood it in the policy's default pose
    np.testing.assert_allclose(robot.entity.data.joint_pos[0].numpy(), contract["default_joint_pos"], atol=1e-9)
    world.add_physics_callback("walk", lambda _dt: handler((0.3, 0.0, 0.0)))
    for _ in range(41):
        world.step(render=False)
    walker_targets = world.engine.ctrl[0].clone()
    handler.hand_over()  # before a joint command: the articulation takes over the walker's last targets
    assert float((world.engine.ctrl[0] - walker_targets).abs().max()) == 0.0
    slow = humanoid_world(SceneCfg(physics_dt_s=0.01, camera=False))
    refusal = default_cmd_vel_handler(slow.scene.get_object("humanoid"), slow.get_physics_dt())
    assert isinstance(refusal, NoWalkingPolicy)
    assert "trained at physics_dt 0.005 s and this World steps 0.01 s" in refusal.problem


def test_joint_target_checks():
    names, limits = ["a", "b"], np.array([[-1.0, 1.0], [-np.inf, np.inf]])
    assert targets_problem([0.5, 100.0], names, limits) is None
    assert "got 3 values for 2 joints" in targets_problem([0, 0, 0], names, limits)
    assert "value nan for joint 'b'" in targets_problem([0, math.nan], names, limits)
    assert "target 1.5 for joint 'a' is outside its range [-1, 1]" in targets_problem([1.5, 0], names, limits)
    assert names_problem(["a"], names) is None
    assert "unknown joint name 'c'" in names_problem(["a", "c"], names)
    assert "more than once" in names_problem(["a", "a"], names)


def test_camera_info_and_stamps():
    pytest.importorskip("sensor_msgs")
    from ambulo.ros2 import messages as m

    t = m.stamp(1.23456789012)
    assert (t.sec, t.nanosec) == (1, 234567890)
    info = m.camera_info(0.0, "cam", 6, 4, [[5, 0, 2.5], [0, 5, 1.5], [0, 0, 1]])
    assert list(info.p) == [5, 0, 2.5, 0, 0, 5, 1.5, 0, 0, 0, 1, 0]


def test_xyzw_reorders_mujoco_quaternions():
    from ambulo.ros2.frames import xyzw

    assert xyzw([0.5, 0.1, 0.2, 0.3]).tolist() == [0.1, 0.2, 0.3, 0.5]


def _same_as_rosbags(data: bytes, typename: str):
    """``data`` decodes with rosbags and re-encodes to the same bytes; returns the message."""
    msg = typestore().deserialize_cdr(data, typename)
    assert bytes(typestore().serialize_cdr(msg, typename)) == data
    return msg


@pytest.mark.parametrize("names", [[], ["a"], ["left_wheel_joint", "rj", "abc"]])
def test_joint_state_bytes_equal_rosbags_and_decode_with_rclpy(names):
    from ambulo.ros2 import cdr

    n = len(names)
    values = {k: np.arange(n) * s for k, s in (("position", 1.5), ("velocity", -2.0), ("effort", 0.25))}
    data = cdr.joint_state_template(names).fill(123_456_789_012, **(values if n else {}))
    msg = _same_as_rosbags(data, "sensor_msgs/msg/JointState")
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.name) == (123, 456_789_012, names)
    np.testing.assert_array_equal(msg.position, values["position"])
    np.testing.assert_array_equal(msg.effort, values["effort"])
    rclpy_serialization = pytest.importorskip("rclpy.serialization")
    from sensor_msgs.msg import JointState

    decoded = rclpy_serialization.deserialize_message(data, JointState)  # real rosidl typesupport
    assert list(decoded.velocity) == values["velocity"].tolist()


def test_imu_odometry_tf_clock_image_bytes_equal_rosbags():
    from ambulo.ros2 import cdr

    cov = np.arange(9.0)
    imu = _same_as_rosbags(cdr.imu_template("imu").fill(7, values=np.concatenate(
        [[0.1, 0.2, 0.3, 0.9], np.zeros(9), [1, 2, 3], cov, [4, 5, 9.81], 2 * cov])), "sensor_msgs/msg/Imu")
    assert (imu.header.frame_id, imu.orientation.w, imu.linear_acceleration.z) == ("imu", 0.9, 9.81)
    np.testing.assert_array_equal(imu.angular_velocity_covariance, cov)
    odom = _same_as_rosbags(cdr.odometry_template("odom", "base_link").fill(8, values=np.concatenate(
        [[1, 2, 3], [0, 0, 0, 1], np.zeros(36), [0.3, 0, 0], [0, 0, 0.5], np.zeros(36)])), "nav_msgs/msg/Odometry")
    assert (odom.child_frame_id, odom.pose.pose.position.z, odom.twist.twist.angular.z) == ("base_link", 3, 0.5)
    tf = _same_as_rosbags(cdr.tf_template(["odom", "base_link"], ["base_link", "wheel"]).fill(
        9, t0=[1, 2, 3, 0, 0, 0, 1], t1=[0, 0.05, 0, 0, 0.6, 0, 0.8]), "tf2_msgs/msg/TFMessage")
    assert [t.child_frame_id for t in tf.transforms] == ["base_link", "wheel"]
    assert tf.transforms[1].transform.rotation.y == 0.6 and tf.transforms[1].header.stamp.nanosec == 9
    assert _same_as_rosbags(cdr.clock(5_000_000_001), "rosgraph_msgs/msg/Clock").clock.sec == 5
    pixels = np.arange(24, dtype=np.uint8).reshape(2, 4, 3)
    img = _same_as_rosbags(cdr.image(1, "cam", 2, 4, "rgb8", 12, pixels.tobytes()), "sensor_msgs/msg/Image")
    assert (img.height, img.width, img.encoding, img.step) == (2, 4, "rgb8", 12)
    assert bytes(img.data) == pixels.tobytes()


def test_relative_poses_of_links():
    from ambulo.ros2.frames import relative
    from ambulo.utils.rotations import quat_to_mat

    yaw = np.array([np.cos(0.25), 0, 0, np.sin(0.25)])  # 0.5 rad about z
    pos, quat = relative(np.array([[1.0, 2, 0]]), yaw[None], np.array([[1.0, 3, 0]]), yaw[None])
    np.testing.assert_allclose(pos[0], quat_to_mat(yaw).T @ [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(quat[0], [1, 0, 0, 0], atol=1e-12)


def test_urdf_rpy_rebuilds_the_rotation():
    import mujoco

    from ambulo.ros2.urdf import rpy

    rng = np.random.default_rng(0)
    for quat in [np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0, 0]), *rng.normal(size=(20, 4))]:
        quat = quat / np.linalg.norm(quat)
        roll, pitch, yaw = rpy(quat)
        rebuilt = np.empty(4)  # URDF: R = Rz(yaw) Ry(pitch) Rx(roll)
        mujoco.mju_euler2Quat(rebuilt, np.array([roll, pitch, yaw]), "XYZ")
        assert abs(abs(rebuilt @ quat) - 1) < 1e-12
    np.testing.assert_allclose(rpy([np.cos(np.pi / 4), np.sin(np.pi / 4), 0, 0]), [np.pi / 2, 0, 0], atol=1e-12)


def test_urdf_of_the_humanoid_draws_capsules_as_cylinder_and_caps():
    import xml.etree.ElementTree as ET

    from ambulo.ros2 import SceneCfg, humanoid_world
    from ambulo.ros2.frames import robot_frames
    from ambulo.ros2.urdf import robot_description

    world = humanoid_world(SceneCfg(camera=False))
    robot = world.scene.get_object("humanoid")
    frames = robot_frames(world.model, robot, "humanoid", "", "odom", "base_link")
    urdf = ET.fromstring(robot_description(world.model, [frames], "odom"))
    assert {link.get("name") for link in urdf.findall("link")} == {"base_link", *robot.entity.body_names[1:]}
    model = world.model
    capsules = sum(int(t) == int(mujoco_geom("capsule")) for t in model.geom_type[model.geom_bodyid > 1])
    assert len(urdf.findall(".//cylinder")) >= capsules
    knee = [j for j in urdf.findall("joint") if j.find("child").get("link") == "left_shank"][0]
    assert knee.get("type") == "revolute" and float(knee.find("limit").get("upper")) == pytest.approx(2.4)


def mujoco_geom(name: str):
    import mujoco

    return getattr(mujoco.mjtGeom, f"mjGEOM_{name.upper()}")


def test_tf_bytes_decode_with_mcap_ros2():
    """Our /tf encoder against an independent decoder (mcap_ros2) over the .msg text."""
    from mcap_ros2._dynamic import generate_dynamic

    from ambulo.ros2.cdr import tf_message

    cdr = tf_message(2_500_000_000, ["odom", "base_link"], ["base_link", "wheel"], [[1, 2, 3], [0, 0.05, 0]],
                     [[0, 0, 0, 1], [0, 0.8, 0, 0.6]])
    msgdef, _ = typestore().generate_msgdef("tf2_msgs/msg/TFMessage", ros_version=2)
    decoded = generate_dynamic("tf2_msgs/msg/TFMessage", msgdef)["tf2_msgs/msg/TFMessage"](cdr)
    a, b = decoded.transforms
    assert (a.header.frame_id, a.child_frame_id, a.header.stamp.sec, a.header.stamp.nanosec) == (
        "odom", "base_link", 2, 500_000_000)
    assert (a.transform.translation.x, a.transform.translation.z, a.transform.rotation.w) == (1, 3, 1)
    assert (b.transform.rotation.y, b.transform.rotation.w) == (0.8, 0.6)


def test_frame_ring_passes_images_in_order_and_refuses_when_full():
    """What the physics thread writes into a slot is what the publisher process takes, byte for byte,
    oldest first; a full ring refuses (the bridge then waits or drops) and a taken slot is reused."""
    import os

    from ambulo.ros2 import cdr
    from ambulo.ros2.frame_ring import FrameRing, slot_bytes_for

    width, height = 8, 4
    writer, fd = FrameRing.create(2, slot_bytes_for(width, height, "cam"))
    reader = FrameRing(fd, 2, writer.slot_bytes)  # the publisher process's mapping of the same memory
    os.close(fd)
    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 255, (height, width, 3), dtype=np.uint8) for _ in range(3)]
    prefixes = [cdr.image_prefix(i, "cam", height, width, "rgb8", 3 * width, frames[i].nbytes) for i in range(3)]
    sizes = [writer.put(prefixes[i], frames[i]) for i in range(2)]
    assert writer.put(prefixes[2], frames[2]) is None  # both slots wait for the reader
    assert reader.take(sizes[0]) == cdr.image(0, "cam", height, width, "rgb8", 3 * width, frames[0].tobytes())
    size = writer.put(prefixes[2], frames[2])  # the freed slot takes the next frame
    assert reader.take(sizes[1]) == cdr.image(1, "cam", height, width, "rgb8", 3 * width, frames[1].tobytes())
    assert reader.take(size) == cdr.image(2, "cam", height, width, "rgb8", 3 * width, frames[2].tobytes())
    depth = np.ones((height, width), "<f4")
    with pytest.raises(ValueError, match="restart the bridge"):
        writer.put(b"", np.ones((64, 64), "<f8"))  # a frame larger than the slots (4 KiB)
    assert writer.put(cdr.image_prefix(3, "cam", height, width, "32FC1", 4 * width, depth.nbytes), depth) is not None
    writer.close()
    reader.close()
