"""How a ``Ros2Bridge`` starts its publisher process: the spec it sends, and ``PublisherProcess``.

The spec lists the topics to advertise (``advertised_topics``), lays out the shared-memory ring (which
state arrays each snapshot copies: ``snapshot_sources``) and carries the static messages
(robot_description, /tf_static: ``static_messages``). ``PublisherProcess`` starts
``python -m ambulo.ros2.publisher`` with the ring, a socket and a wake-up pipe, sends it the spec,
waits for its answer (the topics' full names, the node's name, the Foxglove port), then listens on the
socket for what the process forwards (commands, subscription counts, its final counts).
"""

from __future__ import annotations

import atexit
import logging
import os
import socket
import subprocess
import sys
import threading
import weakref
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from . import cdr
from .frame_ring import FrameRing, slot_bytes_for
from .frames import leaf, xyzw
from .ring import CLOCK, IMU0, JOINT_STATES, ODOM, TF, Layout, Ring

log = logging.getLogger("ambulo.ros2")
FRAME_SLOTS = 4
"""Serialized images that may wait for the publisher process (rgb and depth of two frames)."""
IMU_VALUES = 37
"""An Imu message's numbers in a ring block: orientation (4), its covariance (9), angular velocity (3),
its covariance (9), linear acceleration (3), its covariance (9)."""
ODOM_VALUES = 85
"""An Odometry message's numbers: position (3), orientation (4), pose covariance (36), twist (6),
twist covariance (36)."""


def advertised_topics(scene, cfg) -> list[tuple[str, str, str, str]]:
    """(key, message type, topic, kind) of every publisher; kind: ``data`` (a snapshot's), ``tf``,
    ``static`` (latched, transient-local) or ``camera``."""
    pubs = [("clock", "rosgraph_msgs/msg/Clock", cfg.clock_topic, "data"),
            ("tf", "tf2_msgs/msg/TFMessage", "/tf", "tf"),
            ("tf_static", "tf2_msgs/msg/TFMessage", "/tf_static", "static")]
    if scene.robots:  # robot_state_publisher's QoS: late rviz2 displays still get it
        pubs.append(("robot_description", "std_msgs/msg/String", cfg.robot_description_topic, "static"))
    if scene.joint_names:
        pubs.append(("joint_states", "sensor_msgs/msg/JointState", cfg.joint_states_topic, "data"))
    if scene.robot is not None:
        pubs.append(("odom", "nav_msgs/msg/Odometry", cfg.odom_topic, "data"))
    for i, imu in enumerate(scene.imus):
        topic = cfg.imu_topic if len(scene.imus) == 1 else f"{cfg.imu_topic}/{leaf(imu.prim_path)}"
        pubs.append((f"imu{i}", "sensor_msgs/msg/Imu", topic, "data"))
    for i, camera in enumerate(scene.cameras):
        base = cfg.camera_namespace if len(scene.cameras) == 1 else f"{cfg.camera_namespace}/{leaf(camera.prim_path)}"
        pubs.append((f"rgb{i}", "sensor_msgs/msg/Image", f"{base}/image_raw", "camera"))
        if cfg.publish_depth:
            pubs.append((f"depth{i}", "sensor_msgs/msg/Image", f"{base}/depth", "camera"))
        pubs.append((f"info{i}", "sensor_msgs/msg/CameraInfo", f"{base}/camera_info", "camera"))
    for i, lidar in enumerate(scene.lidars):
        suffix = "" if len(scene.lidars) == 1 else f"/{leaf(lidar.prim_path)}"
        if lidar.shape[0] == 1:
            pubs.append((f"lidar{i}", "sensor_msgs/msg/LaserScan", cfg.scan_topic + suffix, "data"))
        else:
            pubs.append((f"lidar{i}", "sensor_msgs/msg/PointCloud2", cfg.points_topic + suffix, "data"))
    return pubs


def state_topics(scene, cfg) -> list[tuple[int, str, float | None]]:
    """(ring flag bit, key, rate Hz or None: every step) of the topics published from ring snapshots."""
    topics = [(CLOCK, "clock", cfg.clock_rate_hz)]
    if scene.joint_names:
        topics.append((JOINT_STATES, "joint_states", cfg.joint_states_rate_hz))
    if scene.robots:
        topics.append((TF, "tf", cfg.tf_rate_hz))
    if scene.robot is not None:
        topics.append((ODOM, "odom", cfg.odom_rate_hz))
    return topics + [(IMU0 << i, f"imu{i}", cfg.imu_rate_hz) for i in range(len(scene.imus))]


@dataclass
class SnapshotSources:
    """What each ring snapshot copies, and from where.

    ``sources``: block name (``qpos``, ``qvel``, ``qfrc``, ``xpos``, ``xquat``, ``sensordata``) -> world
    0's row of that engine array as flat NumPy (a view on the CPU, else a staging copy); ``staged``:
    (staging copy, function giving the current row) to refresh before each snapshot; ``imu_fast[i]``:
    IMU ``i``'s reading goes as the engine has it (no noise model), from ``sensordata``; ``imus``: the
    publisher process's per-IMU spec; ``odom_free``: the floating robot's (qpos, dof) addresses.
    """

    layout: Layout
    sources: dict[str, np.ndarray] = field(default_factory=dict)
    staged: list[tuple[np.ndarray, Callable[[], np.ndarray]]] = field(default_factory=list)
    imu_fast: list[bool] = field(default_factory=list)
    imus: list[dict] = field(default_factory=list)
    odom_free: tuple | None = None


def imu_is_clean(imu) -> bool:
    noise = imu.cfg.noise
    return not any((noise.gyro_noise_density, noise.accel_noise_density, noise.gyro_random_walk,
                    noise.accel_random_walk, noise.gyro_turn_on_bias_std, noise.accel_turn_on_bias_std))


def snapshot_sources(world, cfg, scene) -> SnapshotSources:
    """The ring layout and the arrays each snapshot copies (numpy views where the engine is on the CPU)."""
    engine = world.engine
    out = SnapshotSources(Layout(slots=max(2, int(cfg.snapshot_slots))))
    floating = scene.robot is not None and scene.robot.entity.is_floating
    if floating:
        out.odom_free = (scene.robot.entity._free_qpos, scene.robot.entity._free_dof)
    for imu in scene.imus:
        out.imu_fast.append(imu_is_clean(imu) and imu.cfg.include_gravity)  # the engine's reading as it is
        rate_hz = 1.0 / (imu.update_period_s or world.get_physics_dt())
        noise = imu.cfg.noise
        # white noise of density sigma_c (unit/sqrt(Hz)) sampled at rate f has variance sigma_c^2 f
        out.imus.append({"frame": scene.sensor_frame[id(imu)], "gyro_var": noise.gyro_noise_density ** 2 * rate_hz,
                         "acc_var": noise.accel_noise_density ** 2 * rate_hz,
                         "adr": (imu._adr["acc"], imu._adr["gyro"], imu._adr["quat"]) if out.imu_fast[-1] else None})
    getters = {"qpos": lambda: engine.qpos, "qvel": lambda: engine.qvel, "qfrc": lambda: engine.qfrc_actuator,
               "xpos": lambda: engine.field("xpos"), "xquat": lambda: engine.field("xquat"),
               "sensordata": lambda: engine.field("sensordata")}
    wanted = []
    if scene.joint_names or floating:
        wanted += ["qpos", "qvel", "qfrc"]
    if scene.robots:
        wanted += ["xpos", "xquat"]
    if any(out.imu_fast):
        wanted.append("sensordata")
    for name in wanted:
        out.sources[name], get = _numpy_source(getters[name])
        if get is not None:  # not on the CPU: copied out before each snapshot
            out.staged.append((out.sources[name], get))
        out.layout.add(name, out.sources[name].size)
    if scene.robot is not None and not floating:
        out.layout.add("odom", ODOM_VALUES)
    for i, fast in enumerate(out.imu_fast):
        if not fast:
            out.layout.add(f"imu{i}", IMU_VALUES)
    return out


def static_messages(world, cfg, scene, serialize) -> tuple[list[tuple[str, bytes, int]], str | None]:
    """((key, serialized message, stamp ns) of robot_description and /tf_static, the URDF or None)."""
    ns = int(round(world.current_time * 1e9))
    static, urdf = [], None
    if scene.robots:
        from std_msgs.msg import String

        from .urdf import robot_description

        urdf = robot_description(world.model, scene.robots, cfg.frame_prefix + cfg.odom_frame)
        static.append(("robot_description", serialize(String(data=urdf)), ns))
    frames = [f for r in scene.robots for f in r.static] + scene.sensor_frames
    if frames:
        static.append(("tf_static", cdr.tf_message(
            ns, [f.parent for f in frames], [f.child for f in frames], np.array([f.pos for f in frames]),
            xyzw(np.array([f.quat_wxyz for f in frames]))), ns))
    return static, urdf


def publisher_spec(cfg, scene, snapshot: SnapshotSources, static: list) -> dict:
    """What the publisher process is told at start: publishers, ring layout, static messages, and the
    indices it needs to turn a snapshot into JointState, TFMessage, Odometry and Imu messages."""
    robots, links = scene.robots, scene.links
    return {"cfg": cfg, "publishers": advertised_topics(scene, cfg), "layout": snapshot.layout, "static": static,
            "subscribe": scene.robot is not None, "joint_names": scene.joint_names,
            "tf_parents": [link.parent for link in links], "tf_children": [link.child for link in links],
            "odom_frame": cfg.frame_prefix + cfg.odom_frame, "base_frame": scene.base_frame,
            "qpos_idx": np.concatenate([r.robot.entity._qpos_adr for r in robots] or [np.zeros(0, int)]),
            "dof_idx": np.concatenate([r.robot.entity._dof_adr for r in robots] or [np.zeros(0, int)]),
            "link_bodies": [link.body for link in links], "link_parents": [link.parent_body for link in links],
            "odom_free": snapshot.odom_free, "imus": snapshot.imus}


class PublisherProcess:
    """The node's process: started with ``spec`` (``publisher_spec``), then a socket both ways.

    ``on_command(msg)`` gets each command the process forwards (``twist``, ``joint_array``,
    ``joint_state``), on the listener thread. Attributes: ``ring`` (the snapshot ring), ``header``
    (the ring as int64), ``frames`` (the image ring, or None without cameras), ``topic`` (key -> full
    topic name), ``node_name``, ``foxglove`` (``.port``, or None), ``subscribers`` (topic ->
    (matched subscriptions, wall time of the change)), ``failed`` and, after ``close``, ``published``
    (topic -> count).
    """

    def __init__(self, spec: dict, frame_slot_bytes: int, cfg, on_command: Callable[[tuple], None]):
        from multiprocessing.connection import Connection

        layout = spec["layout"]
        self.on_command = on_command
        self.subscribers: dict[str, tuple[int, float]] = {}
        self.failed: Counter = Counter()
        self.published: dict[str, int] | None = None
        memfd = os.memfd_create("ambulo-ros2-ring")  # anonymous: nothing is left behind, whatever happens
        os.ftruncate(memfd, layout.nbytes)
        self.frames, frames_fd = None, -1
        if frame_slot_bytes:  # images go through shared memory too (frame_ring.py says why)
            self.frames, frames_fd = FrameRing.create(FRAME_SLOTS, frame_slot_bytes)
            spec["frames"] = (frames_fd, FRAME_SLOTS, frame_slot_bytes)
        mine, theirs = socket.socketpair()
        wake_r, self.wake_w = os.pipe()
        os.set_blocking(self.wake_w, False)
        fds = (memfd, theirs.fileno(), wake_r) + ((frames_fd,) if frames_fd >= 0 else ())
        try:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "ambulo.ros2.publisher", str(memfd), str(theirs.fileno()), str(wake_r)],
                pass_fds=fds, stdin=subprocess.DEVNULL)
        finally:
            theirs.close()
            os.close(wake_r)
            if frames_fd >= 0:
                os.close(frames_fd)
        _set_publisher_cpus(self.proc.pid, cfg.publisher_cpus)
        self.ring = Ring(memfd, layout)
        os.close(memfd)
        self.conn = Connection(mine.detach())
        self._send_lock = threading.Lock()
        self.conn.send(spec)
        reply = self.conn.recv() if self.conn.poll(120.0) else ("failed", "no answer in 120 s")
        if reply[0] != "ready":
            self.proc.kill()
            self.proc.wait()
            raise RuntimeError(f"the ROS 2 publisher process did not start: {reply[1]}")
        _, self.topic, self.node_name, port = reply
        self.foxglove = None if port is None else SimpleNamespace(port=port)
        self.header = memoryview(self.ring.map).cast("q")
        """The whole ring as int64 (plain indexing is cheaper than NumPy's for one value)."""
        self._listener = threading.Thread(target=self._listen, name="ros2-bridge-commands", daemon=True)
        self._listener.start()

    def send(self, msg) -> None:
        with self._send_lock:
            self.conn.send(msg)

    def _listen(self) -> None:
        """What the publisher process forwards (commands are checked on this thread, as rclpy's
        executor did)."""
        while True:
            try:
                msg = self.conn.recv()
            except (EOFError, OSError):
                return
            try:
                if msg[0] == "matched":  # (matched, topic, subscriptions now, wall time s)
                    self.subscribers[msg[1]] = (msg[2], msg[3])
                elif msg[0] == "closed":
                    self.published = msg[1]
                    self.failed.update(msg[2])
                    return
                else:
                    self.on_command(msg)
            except Exception as err:  # a command must never end the bridge
                log.error("ROS 2 command %s failed: %s", msg[0], err)

    def close(self) -> None:
        """Ask the process to publish what is queued and leave the ROS graph; wait for it; release
        the rings."""
        try:
            self.send(("close",))
        except OSError:
            pass
        self._listener.join(timeout=60.0)
        try:
            self.proc.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.conn.close()
        os.close(self.wake_w)
        self.header.release()
        self.ring.close()
        if self.frames is not None:
            self.frames.close()


def frame_slot_bytes(scene) -> int:
    """Bytes of one image slot: the largest serialized image of the scene's cameras (0: no cameras)."""
    return max((slot_bytes_for(*c.resolution, scene.sensor_frame[id(c)]) for c in scene.cameras), default=0)


def close_at_exit(bridge) -> None:
    """Close ``bridge`` when the program ends, even through an exception (bag finished, ROS graph left)."""
    atexit.register(_close_at_exit, weakref.ref(bridge))


def _close_at_exit(ref) -> None:
    bridge = ref()
    if bridge is not None:
        bridge.close()


def _set_publisher_cpus(pid: int, cpus) -> None:
    """Apply ``BridgeCfg.publisher_cpus`` to the publisher process (before it starts its threads, which
    inherit the mask). A mask the system refuses (CPUs offline, a container's cpuset) is left alone."""
    if cpus is None or not hasattr(os, "sched_setaffinity"):
        return
    if cpus == "auto":
        allowed = os.sched_getaffinity(0)
        try:
            import ctypes

            here = ctypes.CDLL(None).sched_getcpu()
        except (OSError, AttributeError):
            return
        cpus = allowed - {here}
        if len(allowed) < 2 or not cpus:
            return
    try:
        os.sched_setaffinity(pid, set(cpus))
    except OSError as err:
        log.warning("BridgeCfg.publisher_cpus=%s not applied: %s", cpus, err)


def _numpy_source(get) -> tuple[np.ndarray, object]:
    """World 0's row of the engine array ``get()`` as flat NumPy, and None: a view made once when the
    array lives on the CPU (the engine updates it in place); else a staging copy and a function that
    gives the current row (to copy into it before each snapshot)."""
    tensor = get()
    if tensor.device.type == "cpu":
        return tensor[0].numpy().reshape(-1), None
    return tensor[0].cpu().numpy().reshape(-1).copy(), lambda: get()[0].cpu().numpy().reshape(-1)


def time_source(world):
    """``world.current_time`` as a zero-argument function; a view of the engine's float64 clock on the CPU."""
    t = world.engine.field("time")
    if t.device.type == "cpu" and str(t.dtype) == "torch.float64":
        view = t.numpy()
        return lambda: float(view[0])
    return lambda: world.current_time
