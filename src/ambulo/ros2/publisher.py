"""The bridge's publisher process: the ROS 2 node that turns the physics loop's snapshots into messages.

``Ros2Bridge`` starts it (``python -m ambulo.ros2.publisher MEMFD SOCKFD WAKEFD``) so that building and
publishing messages runs on another core, in parallel with physics. The physics thread only copies the
few state arrays it needs into a ring of slots in shared memory (an anonymous ``memfd``: nothing is
left in /dev/shm, whatever happens); this process reads each slot, fills the CDR templates, publishes
with the slot's simulated stamp, records the bag and feeds Foxglove. Commands it receives go back to
the bridge, which checks and applies them at the next physics step. It dies with the bridge's process
(``PR_SET_PDEATHSIG``), like the in-process node did: a ``kill -9`` leaves the bag unfinished, but this
process still leaves the ROS graph cleanly.

The ring they share is ``ring.py``.
"""

from __future__ import annotations

import os
import select
import signal
import sys
import threading
import time
from collections import Counter

import numpy as np

from .ring import CLOCK, IMU0, JOINT_STATES, ODOM, READ, TF, WAITING, WRITTEN, Ring, fence

SPIN_S = 100e-6
"""How long the publisher process spins on the ring for the next snapshot before it naps (flat out,
snapshots come every few tens of us)."""
NAP_S = 100e-6
NAP_FOR_S = 0.05
NAP_IF_IDLE_UNDER_S = 2e-3
"""Then it naps ``NAP_S`` at a time (its own timer) for up to ``NAP_FOR_S`` before it sleeps until woken.
A wake-up is a write(2) on the physics thread that wakes another CPU: 10-20 us in a virtual machine,
as much as the step itself; napping, the publisher finds a snapshot at most ``NAP_S`` late and the
physics thread never pays for it while topics flow. Naps cost the publisher's core (10 k wake-ups a
second), so it naps only while snapshots come less than ``NAP_IF_IDLE_UNDER_S`` apart (an average of
its idle times): at 1 kHz it naps; at 100 Hz it sleeps until woken, and the physics thread's write,
~1 % of a 10 ms step, is cheaper than the naps (26 % of a core, measured)."""


def quat_rotate_inverse(q_wxyz: np.ndarray, vec: np.ndarray) -> np.ndarray:
    """``ambulo.utils.math.quat_rotate_inverse`` in NumPy (the same operations, in the same order)."""
    w, xyz = q_wxyz[:1], q_wxyz[1:]
    t = 2.0 * np.cross(xyz, vec)
    return vec - w * t + np.cross(xyz, t)


def _xyzw(q: np.ndarray) -> np.ndarray:
    return q[[1, 2, 3, 0]]


class Publisher:
    """The node, its publishers and subscriptions, built from the bridge's ``spec`` (a dict)."""

    def __init__(self, spec: dict, conn, ring: Ring):
        from . import cdr
        from .runtime import import_rclpy, use_fastdds_profile

        self.spec, self.conn, self.ring, self.cdr = spec, conn, ring, cdr
        cfg = self.cfg = spec["cfg"]
        rclpy = import_rclpy()
        if cfg.fastdds_profile:
            use_fastdds_profile()
        self.published: Counter = Counter()
        self.failed: Counter = Counter()
        from rclpy._rclpy_pybind11 import RCLError

        self._rcl_error = RCLError
        self._send_lock = threading.Lock()
        self._recorder = self.foxglove = None
        if cfg.record:
            from .bag import BagRecorder

            self._recorder = BagRecorder(cfg.record)
        if cfg.foxglove_port is not None:
            from .foxglove_server import FoxgloveServer

            self.foxglove = FoxgloveServer(cfg.foxglove_port)
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(cfg.node_name, namespace=cfg.namespace or None, context=self.context)
        self._make_publishers()
        self._templates = {"joint_states": cdr.joint_state_template(spec["joint_names"]),
                           "tf": cdr.tf_template(spec["tf_parents"], spec["tf_children"]),
                           "odom": cdr.odometry_template(spec["odom_frame"], spec["base_frame"])}
        self._imus = spec["imus"]
        for i, imu in enumerate(self._imus):
            self._templates[f"imu{i}"] = cdr.imu_template(imu["frame"])
        self._qpos_idx, self._dof_idx = np.asarray(spec["qpos_idx"], int), np.asarray(spec["dof_idx"], int)
        self._link_bodies, self._link_parents = np.asarray(spec["link_bodies"], int), np.asarray(spec["link_parents"], int)
        for key, data, ns in spec["static"]:
            self.publish(key, data, ns)
        from rclpy.executors import SingleThreadedExecutor

        self._executor = SingleThreadedExecutor(context=self.context)
        self._executor.add_node(self.node)
        self._stop = threading.Event()
        self._spinner = threading.Thread(target=self._spin, name="ros2-publisher-executor", daemon=True)
        self._spinner.start()

    def _make_publishers(self) -> None:
        from geometry_msgs.msg import Twist
        from nav_msgs.msg import OccupancyGrid, Odometry
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import CameraInfo, Image, Imu, JointState, LaserScan, PointCloud2
        from std_msgs.msg import Float64MultiArray, String

        from .raw_types import raw_message_class

        cfg = self.cfg
        data = QoSProfile(depth=cfg.data_qos_depth, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
        # tf2_ros's broadcasters: /tf keep-last 100, /tf_static transient-local keep-last 1
        qos = {"data": data,
               "tf": QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE),
               "static": QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                    durability=DurabilityPolicy.TRANSIENT_LOCAL),
               "camera": qos_profile_sensor_data if cfg.camera_qos == "sensor_data" else data}
        types = {"rosgraph_msgs/msg/Clock": Clock, "std_msgs/msg/String": String, "nav_msgs/msg/Odometry": Odometry,
                 "nav_msgs/msg/OccupancyGrid": OccupancyGrid,
                 "sensor_msgs/msg/JointState": JointState, "sensor_msgs/msg/Imu": Imu, "sensor_msgs/msg/Image": Image,
                 "sensor_msgs/msg/CameraInfo": CameraInfo, "sensor_msgs/msg/LaserScan": LaserScan,
                 "sensor_msgs/msg/PointCloud2": PointCloud2,
                 "tf2_msgs/msg/TFMessage": raw_message_class("tf2_msgs/msg/TFMessage")}
        self._types, self._qos = types, qos
        self._pubs: dict[str, tuple] = {}
        for key, typename, topic, kind in self.spec["publishers"]:
            self.advertise(key, typename, topic, kind)
        if self.spec["subscribe"]:
            self.node.create_subscription(Twist, cfg.cmd_vel_topic, self._on_twist, 10)
            self.node.create_subscription(Float64MultiArray, cfg.joint_command_topic, self._on_joint_array, 10)
            self.node.create_subscription(JointState, cfg.joint_state_command_topic, self._on_joint_state, 10)

    def advertise(self, key: str, typename: str, topic: str, kind: str) -> str:
        """Create the writer ``key`` (QoS ``kind``: data, tf, static, camera); returns its full topic name."""
        from rclpy.event_handler import PublisherEventCallbacks
        from rclpy.qos import DurabilityPolicy, ReliabilityPolicy

        from .bag import bag_qos
        from .raw_types import clear_rcutils_error

        profile = self._qos[kind]
        # the full name before the writer exists: its matched event may fire (in the executor thread)
        # before create_publisher returns
        name = self.node.resolve_topic_name(topic)
        matched = PublisherEventCallbacks(matched=lambda info: self._on_matched(name, info))
        if typename not in self._types:  # a type declared by the project, e.g. vision_msgs (detections.py)
            from .detections import DETECTION_ARRAY, detection_array_class

            if typename == DETECTION_ARRAY:
                self._types[typename] = detection_array_class()
        pub = self.node.create_publisher(self._types[typename], topic, profile, event_callbacks=matched)
        clear_rcutils_error()
        offered = bag_qos(reliable=profile.reliability == ReliabilityPolicy.RELIABLE,
                          transient_local=profile.durability == DurabilityPolicy.TRANSIENT_LOCAL, depth=profile.depth)
        self._pubs[key] = (pub, typename, offered, pub.topic_name)
        return pub.topic_name

    def _on_matched(self, topic: str, info) -> None:
        """A subscription matched (or left) our writer on ``topic``: the bridge keeps the count and the wall
        time of the change (``Ros2Bridge.subscribers``), e.g. to know from when a subscriber gets everything."""
        self.send(("matched", topic, int(info.current_count), time.time()))

    # -- commands: forwarded as they are; the bridge checks and applies them ------------------------
    def send(self, msg) -> None:
        with self._send_lock:
            self.conn.send(msg)

    def _on_twist(self, msg) -> None:
        self.send(("twist", (msg.linear.x, msg.linear.y, msg.linear.z), (msg.angular.x, msg.angular.y, msg.angular.z)))

    def _on_joint_array(self, msg) -> None:
        self.send(("joint_array", list(msg.data)))

    def _on_joint_state(self, msg) -> None:
        self.send(("joint_state", list(msg.name), list(msg.position)))

    def _spin(self) -> None:
        while not self._stop.is_set() and self.context.ok():
            try:
                self._executor.spin_once(timeout_sec=0.05)
            except Exception as err:  # shutting down under the executor
                if not self._stop.is_set():
                    print(f"ambulo.ros2 publisher: executor stopped: {err}", file=sys.stderr)
                return

    # -- publishing -----------------------------------------------------------------------------
    def publish(self, key: str, data: bytes, stamp_ns: int) -> None:
        pub, typename, qos, topic = self._pubs[key]
        try:
            pub.publish(data)  # CDR bytes go out as a serialized message, as they are
        except self._rcl_error as err:  # e.g. a reliable writer's history stayed full past its
            self.failed[topic] += 1  # max_blocking_time: that message is lost, the next ones go on
            if self.failed[topic] == 1:
                self.node.get_logger().warning(f"{topic}: a message could not be published: {err}")
            return
        self.published[topic] += 1
        if self._recorder is not None:
            self._recorder.write(topic, typename, qos, data, stamp_ns)
        if self.foxglove is not None:
            self.foxglove.log(topic, typename, data, stamp_ns)

    def drain(self, upto: int | None = None) -> None:
        """Publish every slot written so far (or up to ``upto``), oldest first."""
        header = self.ring.header
        end = int(header[WRITTEN]) if upto is None else upto
        read = int(header[READ])
        while read < end:
            self.publish_slot(read % self.ring.layout.slots)
            read += 1
            header[READ] = read  # the slot may be written again

    def publish_slot(self, slot: int) -> None:
        ring, cdr, t = self.ring, self.cdr, self._templates
        ns, flags = int(ring.irows[slot, 0]), int(ring.irows[slot, 1])
        if flags & CLOCK:
            self.publish("clock", cdr.clock(ns), ns)
            if self.foxglove is not None:
                self.foxglove.broadcast_time(ns)
        if flags & (JOINT_STATES | ODOM):
            qpos, qvel = ring.block(slot, "qpos"), ring.block(slot, "qvel")
        if flags & JOINT_STATES:
            self.publish("joint_states", t["joint_states"].fill(
                ns, position=qpos[self._qpos_idx], velocity=qvel[self._dof_idx],
                effort=ring.block(slot, "qfrc")[self._dof_idx]), ns)
        if flags & TF:
            self.publish("tf", self._tf_cdr(ns, ring.block(slot, "xpos").reshape(-1, 3),
                                            ring.block(slot, "xquat").reshape(-1, 4)), ns)
        if flags & ODOM:
            free = self.spec["odom_free"]
            if free is None:  # computed by the bridge
                values = ring.block(slot, "odom")
            else:  # a floating root: its free joint's coordinates
                fq, fd = free
                quat = qpos[fq + 3:fq + 7]
                values = np.concatenate([qpos[fq:fq + 3], _xyzw(quat), np.zeros(36),
                                         quat_rotate_inverse(quat, qvel[fd:fd + 3]), qvel[fd + 3:fd + 6], np.zeros(36)])
            self.publish("odom", t["odom"].fill(ns, values=values), ns)
        for i, imu in enumerate(self._imus):
            if flags & (IMU0 << i):
                self.publish(f"imu{i}", t[f"imu{i}"].fill(ns, values=self._imu_values(slot, i, imu)), ns)

    def _imu_values(self, slot: int, i: int, imu: dict) -> np.ndarray:
        if imu["adr"] is None:  # noisy (or gravity removed): the bridge's reading
            return self.ring.block(slot, f"imu{i}")
        s = self.ring.block(slot, "sensordata")
        acc, gyro, quat = (s[a:a + n] for a, n in zip(imu["adr"], (3, 3, 4)))
        return np.concatenate([_xyzw(quat), np.zeros(9), gyro, np.diag([imu["gyro_var"]] * 3).ravel(), acc,
                               np.diag([imu["acc_var"]] * 3).ravel()])

    def _tf_cdr(self, ns: int, xpos: np.ndarray, xquat: np.ndarray) -> bytes:
        from .frames import relative

        parents = self._link_parents
        pos_p = np.where(parents[:, None] < 0, 0.0, xpos[np.maximum(parents, 0)])
        quat_p = np.where(parents[:, None] < 0, np.array([1.0, 0, 0, 0]), xquat[np.maximum(parents, 0)])
        pos, quat = relative(pos_p, quat_p, xpos[self._link_bodies], xquat[self._link_bodies])
        poses = np.concatenate([pos, _xyzw_rows(quat)], axis=1)
        return self._templates["tf"].fill(ns, **{f"t{i}": pose for i, pose in enumerate(poses)})

    def close(self) -> None:
        self._stop.set()
        self._spinner.join(timeout=2.0)
        self._executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        self.context.try_shutdown()
        if self._recorder is not None:
            self._recorder.close()
        if self.foxglove is not None:
            self.foxglove.close()


def _xyzw_rows(quat: np.ndarray) -> np.ndarray:
    return quat[..., [1, 2, 3, 0]]


def _die_with_parent() -> None:
    """Get SIGTERM when the bridge's process dies (even by SIGKILL without closing the bridge):
    ``serve`` then leaves the ROS graph (so Fast DDS removes its shared memory) and exits at once,
    leaving the bag unfinished, as a node inside the killed process would have."""
    import ctypes

    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def serve(memfd: int, sockfd: int, wakefd: int) -> int:
    from multiprocessing.connection import Connection

    parent = os.getppid()
    _die_with_parent()
    if os.getppid() != parent:  # the bridge died before we asked to follow it
        return 1
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the bridge's to handle: it closes us
    try:  # naps of NAP_S, not NAP_S + the default 50 us timer slack
        import ctypes

        ctypes.CDLL(None).prctl(29, 5000)  # PR_SET_TIMERSLACK, ns
    except (OSError, AttributeError):
        pass
    conn = Connection(sockfd)
    spec = conn.recv()
    if spec["cfg"].publisher_nice > 0:
        os.nice(spec["cfg"].publisher_nice)
    ring = Ring(memfd, spec["layout"])
    frames = None
    if spec.get("frames") is not None:
        from .frame_ring import FrameRing

        frames_fd, slots, slot_bytes = spec["frames"]
        frames = FrameRing(frames_fd, slots, slot_bytes)
        os.close(frames_fd)
    os.set_blocking(wakefd, False)
    try:
        publisher = Publisher(spec, conn, ring)
    except Exception as err:  # reported to the bridge, which raises it
        conn.send(("failed", f"{type(err).__name__}: {err}"))
        return 1

    def orphaned(_signum=None, _frame=None) -> None:
        signal.signal(signal.SIGALRM, signal.SIG_DFL)
        signal.alarm(3)  # whatever happens below, the kernel ends this process in 3 s
        try:
            publisher._recorder = None  # the bag stays as the crash left it (``--recover`` reads it)
            publisher.close()
        except Exception:  # best effort: exiting anyway
            pass
        finally:
            os._exit(143)

    signal.signal(signal.SIGTERM, orphaned)
    publisher.send(("ready", {key: topic for key, (_, _, _, topic) in publisher._pubs.items()},
                    publisher.node.get_fully_qualified_name(),
                    None if publisher.foxglove is None else publisher.foxglove.port))
    import gc

    gc.freeze()  # the modules' objects (rclpy, NumPy, MuJoCo, ...) need no scanning: a full collection
    # of them would hold every message back for tens of ms
    header = ring.header
    idle_s = 0.0  # average time the ring stays empty between snapshots (an average of the idle spells)
    while True:
        publisher.drain()
        if conn.poll(0):
            try:
                msg = conn.recv()
            except (EOFError, OSError):  # the bridge's process is gone without closing us
                orphaned()
            kind = msg[0]
            if kind == "raw":  # (raw, key, cdr bytes, stamp ns, ring position when sent)
                publisher.drain(msg[4])
                publisher.publish(msg[1], msg[2], msg[3])
            elif kind == "frame":  # (frame, key, bytes in the frame ring's oldest slot, stamp ns, ring position)
                publisher.drain(msg[4])
                publisher.publish(msg[1], frames.take(msg[2]), msg[3])
            elif kind == "advertise":  # (advertise, key, type name, topic, QoS kind): a topic added later
                if msg[1] not in publisher._pubs:
                    publisher.advertise(*msg[1:5])
            elif kind == "warn":
                publisher.node.get_logger().warning(msg[1])  # to the console and /rosout
            elif kind == "close":
                publisher.drain()
                publisher.close()
                publisher.send(("closed", dict(publisher.published), dict(publisher.failed)))
                ring.close()
                if frames is not None:
                    frames.close()
                return 0
            continue
        idle_from = time.perf_counter()
        spin_until = idle_from + SPIN_S  # flat out, the next snapshot comes within tens of us:
        while header[WRITTEN] == header[READ] and time.perf_counter() < spin_until:  # no need to sleep
            time.sleep(0)  # lets the executor thread (commands) take the GIL
        if header[WRITTEN] != header[READ]:
            idle_s = 0.8 * idle_s + 0.2 * (time.perf_counter() - idle_from)
            continue
        nap_until = time.perf_counter() + (NAP_FOR_S if idle_s < NAP_IF_IDLE_UNDER_S else 0.0)
        while header[WRITTEN] == header[READ] and time.perf_counter() < nap_until and not conn.poll(0):
            time.sleep(NAP_S)
        if header[WRITTEN] != header[READ]:
            idle_s = 0.8 * idle_s + 0.2 * (time.perf_counter() - idle_from)
            continue
        if os.getppid() != parent:  # the bridge's process is gone (and SIGTERM did not come)
            orphaned()
        header[WAITING] = 1  # the bridge clears it when it writes the wake-up byte
        fence()  # the store above before the load below (the bridge does the converse)
        if header[WRITTEN] == header[READ]:
            select.select([conn, wakefd], [], [], 0.005)  # the timeout is a safety net only
        header[WAITING] = 0
        idle_s = 0.8 * idle_s + 0.2 * (time.perf_counter() - idle_from)
        try:
            while os.read(wakefd, 4096):
                pass
        except BlockingIOError:
            pass


if __name__ == "__main__":
    sys.exit(serve(*(int(a) for a in sys.argv[1:4])))
