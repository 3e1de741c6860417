"""``PublisherLaunch``: how a ``Ros2Bridge`` starts its publisher process (part of ``Ros2Bridge``, a mixin).

It lists the topics to advertise, lays out the shared-memory ring (which state arrays each snapshot
copies), builds the static messages (robot_description, /tf_static), then starts
``python -m ambulo.ros2.publisher`` with the ring, a socket and a wake-up pipe, sends it the spec and
waits for its answer (the topics' full names, the node's name, the Foxglove port).
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
from types import SimpleNamespace

import numpy as np

from . import cdr
from .frame_ring import FrameRing, slot_bytes_for
from .frames import leaf, xyzw
from .ring import CLOCK, IMU0, JOINT_STATES, ODOM, TF, Layout, Ring
from .runtime import use_fastdds_profile

log = logging.getLogger("ambulo.ros2")
_INF = float("inf")
FRAME_SLOTS = 4
"""Serialized images that may wait for the publisher process (rgb and depth of two frames)."""


class PublisherLaunch:
    """``Ros2Bridge``'s publisher process: ``_start_publisher`` (once, from ``__init__``) and ``_send``."""

    def _start_publisher(self) -> None:
        from multiprocessing.connection import Connection  # noqa: PLC0415

        from rclpy.serialization import serialize_message  # noqa: PLC0415

        self._frames = self._sensor_frames()

        cfg, engine, model = self.cfg, self.world.engine, self.world.model
        self._serialize = serialize_message
        if cfg.fastdds_profile:
            use_fastdds_profile()  # in the environment the publisher process inherits
        pubs: list[tuple] = []

        def publisher(key: str, typename: str, topic: str, kind: str) -> None:
            pubs.append((key, typename, topic, kind))

        publisher("clock", "rosgraph_msgs/msg/Clock", cfg.clock_topic, "data")
        publisher("tf", "tf2_msgs/msg/TFMessage", "/tf", "tf")
        publisher("tf_static", "tf2_msgs/msg/TFMessage", "/tf_static", "static")
        if self.robots:  # robot_state_publisher's QoS: late rviz2 displays still get it
            publisher("robot_description", "std_msgs/msg/String", cfg.robot_description_topic, "static")
        if self.joint_names:
            publisher("joint_states", "sensor_msgs/msg/JointState", cfg.joint_states_topic, "data")
        if self.robot is not None:
            publisher("odom", "nav_msgs/msg/Odometry", cfg.odom_topic, "data")
        for i, imu in enumerate(self.imus):
            topic = cfg.imu_topic if len(self.imus) == 1 else f"{cfg.imu_topic}/{leaf(imu.prim_path)}"
            publisher(f"imu{i}", "sensor_msgs/msg/Imu", topic, "data")
        for i, camera in enumerate(self.cameras):
            base = cfg.camera_namespace if len(self.cameras) == 1 else f"{cfg.camera_namespace}/{leaf(camera.prim_path)}"
            publisher(f"rgb{i}", "sensor_msgs/msg/Image", f"{base}/image_raw", "camera")
            if cfg.publish_depth:
                publisher(f"depth{i}", "sensor_msgs/msg/Image", f"{base}/depth", "camera")
            publisher(f"info{i}", "sensor_msgs/msg/CameraInfo", f"{base}/camera_info", "camera")
        for i, lidar in enumerate(self.lidars):
            suffix = "" if len(self.lidars) == 1 else f"/{leaf(lidar.prim_path)}"
            if lidar.shape[0] == 1:
                publisher(f"lidar{i}", "sensor_msgs/msg/LaserScan", cfg.scan_topic + suffix, "data")
            else:
                publisher(f"lidar{i}", "sensor_msgs/msg/PointCloud2", cfg.points_topic + suffix, "data")

        # what each snapshot copies: numpy views of the engine's arrays where they live on the CPU
        self._state_topics = [(CLOCK, "clock", cfg.clock_rate_hz)]
        if self.joint_names:
            self._state_topics.append((JOINT_STATES, "joint_states", cfg.joint_states_rate_hz))
        if self.robots:
            self._state_topics.append((TF, "tf", cfg.tf_rate_hz))
        if self.robot is not None:
            self._state_topics.append((ODOM, "odom", cfg.odom_rate_hz))
        self._state_topics += [(IMU0 << i, f"imu{i}", cfg.imu_rate_hz) for i in range(len(self.imus))]
        layout = Layout(slots=max(2, int(cfg.snapshot_slots)))
        sources = {"qpos": lambda: engine.qpos, "qvel": lambda: engine.qvel, "qfrc": lambda: engine.qfrc_actuator,
                   "xpos": lambda: engine.field("xpos"), "xquat": lambda: engine.field("xquat"),
                   "sensordata": lambda: engine.field("sensordata")}
        floating = self.robot is not None and self.robot.entity.is_floating
        odom_free = (self.robot.entity._free_qpos, self.robot.entity._free_dof) if floating else None
        imus, self._imu_fast = [], []
        rate_of = [1.0 / (imu.update_period_s or self.world.get_physics_dt()) for imu in self.imus]
        for i, imu in enumerate(self.imus):
            noise = imu.cfg.noise
            clean = not any((noise.gyro_noise_density, noise.accel_noise_density, noise.gyro_random_walk,
                             noise.accel_random_walk, noise.gyro_turn_on_bias_std, noise.accel_turn_on_bias_std))
            fast = clean and imu.cfg.include_gravity  # the engine's reading as it is
            self._imu_fast.append(fast)
            # white noise of density sigma_c (unit/sqrt(Hz)) sampled at rate f has variance sigma_c^2 f
            imus.append({"frame": self._sensor_frame[id(imu)], "gyro_var": noise.gyro_noise_density ** 2 * rate_of[i],
                         "acc_var": noise.accel_noise_density ** 2 * rate_of[i],
                         "adr": (imu._adr["acc"], imu._adr["gyro"], imu._adr["quat"]) if fast else None})
        wanted = []
        if self.joint_names or floating:
            wanted += ["qpos", "qvel", "qfrc"]
        if self.robots:
            wanted += ["xpos", "xquat"]
        if any(self._imu_fast):
            wanted.append("sensordata")
        self._sources, self._staged = {}, []
        for name in wanted:
            self._sources[name], get = _numpy_source(sources[name])
            if get is not None:  # not on the CPU: copied out before each snapshot
                self._staged.append((self._sources[name], get))
            layout.add(name, self._sources[name].size)
        if self.robot is not None and not floating:
            layout.add("odom", 85)
        for i, fast in enumerate(self._imu_fast):
            if not fast:
                layout.add(f"imu{i}", 37)
        self._now = _time_source(self.world)

        ns = int(round(self.world.current_time * 1e9))
        static = []
        if self.robots:
            from std_msgs.msg import String  # noqa: PLC0415

            from .urdf import robot_description  # noqa: PLC0415

            self.urdf = robot_description(model, self.robots, cfg.frame_prefix + cfg.odom_frame)
            static.append(("robot_description", serialize_message(String(data=self.urdf)), ns))
        frames = [f for r in self.robots for f in r.static] + self._frames
        if frames:
            self._static_frames = frames
            static.append(("tf_static", cdr.tf_message(
                ns, [f.parent for f in frames], [f.child for f in frames], np.array([f.pos for f in frames]),
                xyzw(np.array([f.quat_wxyz for f in frames]))), ns))
        spec = {"cfg": cfg, "publishers": pubs, "layout": layout, "static": static, "subscribe": self.robot is not None,
                "joint_names": self.joint_names, "tf_parents": [link.parent for link in self._links],
                "tf_children": [link.child for link in self._links],
                "odom_frame": cfg.frame_prefix + cfg.odom_frame, "base_frame": self._base_frame,
                "qpos_idx": np.concatenate([r.robot.entity._qpos_adr for r in self.robots] or [np.zeros(0, int)]),
                "dof_idx": np.concatenate([r.robot.entity._dof_adr for r in self.robots] or [np.zeros(0, int)]),
                "link_bodies": [link.body for link in self._links],
                "link_parents": [link.parent_body for link in self._links], "odom_free": odom_free, "imus": imus}

        memfd = os.memfd_create("ambulo-ros2-ring")  # anonymous: nothing is left behind, whatever happens
        os.ftruncate(memfd, layout.nbytes)
        self._frames, frames_fd = None, -1
        if self.cameras:  # images go through shared memory too (frame_ring.py says why)
            slot_bytes = max(slot_bytes_for(*c.resolution, self._sensor_frame[id(c)])
                             for c in self.cameras)
            self._frames, frames_fd = FrameRing.create(FRAME_SLOTS, slot_bytes)
            spec["frames"] = (frames_fd, FRAME_SLOTS, slot_bytes)
        mine, theirs = socket.socketpair()
        wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_w, False)
        fds = (memfd, theirs.fileno(), wake_r) + ((frames_fd,) if frames_fd >= 0 else ())
        try:
            self._proc = subprocess.Popen(
                [sys.executable, "-m", "ambulo.ros2.publisher", str(memfd), str(theirs.fileno()), str(wake_r)],
                pass_fds=fds, stdin=subprocess.DEVNULL)
        finally:
            theirs.close()
            os.close(wake_r)
            if frames_fd >= 0:
                os.close(frames_fd)
        _set_publisher_cpus(self._proc.pid, cfg.publisher_cpus)
        self._ring = Ring(memfd, layout)
        os.close(memfd)
        self._conn = Connection(mine.detach())
        self._send_lock = threading.Lock()
        self._conn.send(spec)
        reply = self._conn.recv() if self._conn.poll(120.0) else ("failed", "no answer in 120 s")
        if reply[0] != "ready":
            self._proc.kill()
            self._proc.wait()
            raise RuntimeError(f"the ROS 2 publisher process did not start: {reply[1]}")
        _, self._topic, self.node_name, port = reply
        """``node_name``: the node's fully qualified name (it lives in the publisher process)."""
        self.foxglove = None if port is None else SimpleNamespace(port=port)
        self._closed_counts: dict[str, int] | None = None
        self._slot_views = [self._views_of_slot(s) for s in range(layout.slots)]
        self._header = memoryview(self._ring.map).cast("q")
        """The whole ring as int64 (plain indexing is cheaper than NumPy's for one value)."""
        self._slots = layout.slots
        self._read_seen = 0
        """The publisher's ``READ`` counter as last loaded (it only grows, so a stale value is safe)."""
        self._schedule = [[bit, key, 0.0 if rate is None else 1.0 / rate, -_INF, -_INF]
                          for bit, key, rate in self._state_topics]
        self._schedule += [[0, f"camera{i}", 1.0 / self.cfg.camera_rate_hz, -_INF, -_INF] for i in range(len(self.cameras))]
        self._schedule += [[0, f"lidar{i}", 1.0 / self.cfg.lidar_rate_hz, -_INF, -_INF] for i in range(len(self.lidars))]
        self._listener = threading.Thread(target=self._listen, name="ros2-bridge-commands", daemon=True)
        self._listener.start()
        atexit.register(_close_at_exit, weakref.ref(self))  # an exception ending the program still
        # closes the publisher process cleanly (bag finished, ROS graph left)

    def _send(self, msg) -> None:
        with self._send_lock:
            self._conn.send(msg)


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
            import ctypes  # noqa: PLC0415

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


def _time_source(world):
    """``world.current_time`` as a zero-argument function; a view of the engine's float64 clock on the CPU."""
    t = world.engine.field("time")
    if t.device.type == "cpu" and str(t.dtype) == "torch.float64":
        view = t.numpy()
        return lambda: float(view[0])
    return lambda: world.current_time
