"""The oracle: an independent rclpy node, in its own process, that checks the bridge from outside.

It uses only rclpy and the message packages of the PyPI wheels (real Fast DDS, real typesupport),
plus ``mcap_ros2``'s CDR decoder for ``/tf`` (whose message package has no wheel; the bridge
encodes /tf with its own ``ambulo.ros2.cdr``, so the decoder is independent of the encoder). To
take /tf at all it needs a type named ``tf2_msgs/msg/TFMessage``: it loads
``ambulo/ros2/raw_types.py`` by path, the declaration (DDS name and hash) the bridge uses too; a
stock ROS 2 node would use its generated tf2_msgs instead.

Protocol: JSON lines. The oracle prints ``{"event": "ready", "graph": ...}`` once it sees the
bridge's node and topics; then reads commands on stdin, one JSON object a line:
``{"do": "publish", "topic": ..., "type": "twist"|"array"|"joint_state", "data": ..., "times": n}``
and ``{"do": "dump", "path": ...}`` (writes everything received, then exits).
"""

from __future__ import annotations

import importlib.util
import json
import os
import sys
import threading
import time
from pathlib import Path

import rclpy
from geometry_msgs.msg import Twist
from nav_msgs.msg import OccupancyGrid, Odometry
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, Imu, JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, String

RAW_TYPES = Path(__file__).resolve().parents[2] / "src" / "ambulo" / "ros2" / "raw_types.py"
SHARE = Path(sys.prefix) / "share"


def tf_class():
    spec = importlib.util.spec_from_file_location("oracle_raw_types", RAW_TYPES)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.raw_message_class("tf2_msgs/msg/TFMessage")


def tf_decoder():
    """mcap_ros2's decoder over the .msg files the geometry_msgs/std_msgs wheels ship."""
    from mcap_ros2._dynamic import generate_dynamic

    parts = ["geometry_msgs/TransformStamped[] transforms\n"]
    for name in ("geometry_msgs/TransformStamped", "std_msgs/Header", "builtin_interfaces/Time",
                 "geometry_msgs/Transform", "geometry_msgs/Vector3", "geometry_msgs/Quaternion"):
        package, msg = name.split("/")
        text = (SHARE / package / "msg" / f"{msg}.msg").read_text()
        parts.append("=" * 80 + f"\nMSG: {name}\n{text}")
    return generate_dynamic("tf2_msgs/msg/TFMessage", "\n".join(parts))["tf2_msgs/msg/TFMessage"]


def t(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


class Oracle:
    def __init__(self, expect: list[str]):
        self.node = rclpy.create_node("oracle")
        self.expect = expect
        self.got: dict[str, list] = {k: [] for k in ("joint_states", "imu", "clock", "odom", "image", "depth", "info",
                                                      "tf", "tf_static", "robot_description", "costmap")}
        self.lock = threading.Lock()
        decode = tf_decoder()
        TF = tf_class()
        reliable = QoSProfile(depth=10_000, reliability=ReliabilityPolicy.RELIABLE)  # a slow callback loses nothing
        static = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        sub = self.node.create_subscription
        sub(JointState, "/joint_states", lambda m: self.add("joint_states", [t(m.header.stamp), list(m.name),
                                                                             list(m.position), list(m.velocity)]), reliable)
        sub(Imu, "/imu/data", lambda m: self.add("imu", [t(m.header.stamp), m.header.frame_id, m.linear_acceleration.x,
                                                         m.linear_acceleration.y, m.linear_acceleration.z,
                                                         list(m.linear_acceleration_covariance)]), reliable)
        sub(Clock, "/clock", lambda m: self.add("clock", t(m.clock)), reliable)
        sub(Odometry, "/odom", lambda m: self.add("odom", [t(m.header.stamp), m.pose.pose.position.x,
                                                           m.pose.pose.position.y]), reliable)
        sub(Image, "/camera/image_raw", lambda m: self.add("image", self.image(m)), reliable)
        sub(Image, "/camera/depth", lambda m: self.add("depth", self.image(m, with_data=True)), reliable)
        sub(CameraInfo, "/camera/camera_info", lambda m: self.add("info", [t(m.header.stamp), m.width, m.height,
                                                                           list(m.k), m.header.frame_id]), reliable)

        def transforms(raw: bytes) -> list:
            return [[t(x.header.stamp), x.header.frame_id, x.child_frame_id,
                     [x.transform.translation.x, x.transform.translation.y, x.transform.translation.z],
                     [x.transform.rotation.x, x.transform.rotation.y, x.transform.rotation.z, x.transform.rotation.w]]
                    for x in decode(raw).transforms]

        sub(TF, "/tf", lambda raw: self.add("tf", transforms(raw)), reliable, raw=True)
        sub(TF, "/tf_static", lambda raw: self.add("tf_static", transforms(raw)), static, raw=True)
        sub(String, "/robot_description", lambda m: self.add("robot_description", m.data), static)
        sub(OccupancyGrid, "/costmap", lambda m: self.add("costmap", [
            t(m.header.stamp), m.header.frame_id, m.info.resolution, m.info.width, m.info.height,
            m.info.origin.position.x, m.info.origin.position.y, list(m.data)]), static)
        self.pubs = {}

    @staticmethod
    def image(m, with_data: bool = False) -> list:
        item = [t(m.header.stamp), m.width, m.height, m.encoding, m.step, len(m.data), m.header.frame_id]
        if with_data:
            item.append(bytes(m.data).hex())
        return item

    def add(self, key: str, item) -> None:
        with self.lock:
            self.got[key].append(item)

    def graph(self) -> dict:
        node = self.node
        topics = dict(node.get_topic_names_and_types())
        out = {"nodes": [f"{ns.rstrip('/')}/{n}" for n, ns in node.get_node_names_and_namespaces()], "topics": {}}
        for topic, types in topics.items():
            infos = node.get_publishers_info_by_topic(topic)
            out["topics"][topic] = {"types": types, "publishers": [{
                "node": i.node_name, "type": i.topic_type, "hash": str(i.topic_type_hash),
                "reliability": i.qos_profile.reliability.name, "durability": i.qos_profile.durability.name,
                "depth": i.qos_profile.depth} for i in infos]}
        return out

    def wait_ready(self, timeout_s: float = 20.0) -> dict:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=0.05)
            topics = dict(self.node.get_topic_names_and_types())
            subs = self.node.get_subscriptions_info_by_topic("/cmd_vel")
            if all(e in topics for e in self.expect) and subs:
                return self.graph()
        return self.graph()

    def publish(self, cmd: dict) -> None:
        topic, kind = cmd["topic"], cmd["type"]
        if topic not in self.pubs:
            msg_type = {"twist": Twist, "array": Float64MultiArray, "joint_state": JointState}[kind]
            self.pubs[topic] = self.node.create_publisher(msg_type, topic, 10)
            end = time.monotonic() + 5.0
            while self.pubs[topic].get_subscription_count() == 0 and time.monotonic() < end:
                rclpy.spin_once(self.node, timeout_sec=0.02)
        data = cmd["data"]
        if kind == "twist":
            msg = Twist()
            msg.linear.x, msg.linear.y, msg.linear.z, msg.angular.x, msg.angular.y, msg.angular.z = (
                float(v) for v in data)
        elif kind == "array":
            msg = Float64MultiArray(data=[float(v) for v in data])
            msg.layout.dim = [MultiArrayDimension(label="joints", size=len(data), stride=len(data))]
        else:
            msg = JointState(name=data["name"], position=[float(v) for v in data["position"]])
        for _ in range(cmd.get("times", 1)):
            self.pubs[topic].publish(msg)
            rclpy.spin_once(self.node, timeout_sec=0.01)


def main() -> int:
    expect = json.loads(sys.argv[1]) if len(sys.argv) > 1 else ["/joint_states"]
    rclpy.init()
    oracle = Oracle(expect)
    print(json.dumps({"event": "ready", "graph": oracle.wait_ready()}), flush=True)
    commands: list[dict] = []
    reader = threading.Thread(target=lambda: [commands.append(json.loads(line)) for line in sys.stdin], daemon=True)
    reader.start()
    while True:
        rclpy.spin_once(oracle.node, timeout_sec=0.01)
        while commands:
            cmd = commands.pop(0)
            if cmd["do"] == "publish":
                oracle.publish(cmd)
                print(json.dumps({"event": "published", "topic": cmd["topic"]}), flush=True)
            elif cmd["do"] == "dump":
                until_ns, deadline = cmd.get("until_clock_ns"), time.monotonic() + 100.0
                while until_ns is not None and time.monotonic() < deadline:  # starved of CPU: catch up
                    with oracle.lock:
                        if oracle.got["clock"] and oracle.got["clock"][-1] >= until_ns:
                            break
                    rclpy.spin_once(oracle.node, timeout_sec=0.02)
                end = time.monotonic() + cmd.get("linger_s", 0.5)
                while time.monotonic() < end:  # what is still in flight
                    rclpy.spin_once(oracle.node, timeout_sec=0.02)
                with oracle.lock:
                    Path(cmd["path"]).write_text(json.dumps({"got": oracle.got, "graph": oracle.graph()},
                                                            allow_nan=True))
                print(json.dumps({"event": "dumped"}), flush=True)
                # DDS teardown has hung on CI after the dump (the scenario then waited on our pipes
                # until its timeout); nothing is left to lose, so a watchdog ends the process.
                threading.Timer(10.0, os._exit, args=(0,)).start()
                oracle.node.destroy_node()
                rclpy.try_shutdown()
                return 0
        if not reader.is_alive() and not commands:
            return 1


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    sys.exit(main())
