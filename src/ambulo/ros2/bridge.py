"""``Ros2Bridge``: a World as a real ROS 2 node (rclpy), publishing its state and taking commands.

The node lives in a separate publisher process (``publisher.py``), so that building and publishing
messages runs on another core, in parallel with physics. The physics thread pays only for a snapshot:
in a physics callback, before each physics step, it copies the few state arrays that the due topics
need (joint coordinates, body poses, sensor data) into a ring of slots in shared memory, stamped with
the simulated time; the publisher process turns each slot into messages, stamped with that time, so
every message describes one consistent state. Topics are published at their configured rates of
simulated time. When the simulation outruns the publisher (stepping flat out with topics every
step), the bridge waits for a free slot (``BridgeCfg.drop_when_behind=False``, the default: every
message goes out, the bag is complete) or skips the snapshot and counts it in ``dropped``.

Commands arrive in the publisher process and come back to the bridge, where a thread checks them (a
bad one is dropped with a warning naming the problem) and the latest good one is applied at the next
physics step, so the physics loop never waits on the network. A velocity command holds until the next
one (no timeout), for the Jetbot and the humanoid alike.

The bundled humanoid follows /cmd_vel through the shipped walking policy (``WalkingPolicyDrive``):
attaching stands it in the policy's default pose and the policy then runs every physics step,
walking in place until the first Twist; a joint command pauses it until the next Twist.
"""

from __future__ import annotations

import atexit
import logging
import math
import os
import socket
import subprocess
import sys
import threading
import time
import weakref
from collections import Counter
from types import SimpleNamespace

import numpy as np

from . import cdr
from . import messages as m
from .commands import CmdVelHandler, default_cmd_vel_handler, names_problem, targets_problem, twist_problem
from .config import BridgeCfg
from .frame_ring import FrameRing, slot_bytes_for
from .frames import OPTICAL_FROM_GL, leaf, robot_frames, static_from_world, xyzw
from .publisher import _FENCE, CLOCK, HEADER_BYTES, IMU0, JOINT_STATES, ODOM, READ, TF, WAITING, WRITTEN, Layout, Ring
from .runtime import import_rclpy, use_fastdds_profile

log = logging.getLogger("ambulo.ros2")
_INF = float("inf")
FRAME_SLOTS = 4
"""Serialized images that may wait for the publisher process (rgb and depth of two frames)."""


class Ros2Bridge:
    """Attach a ROS 2 node to ``world`` (already ``reset()``); ``close()`` (or ``with``) detaches it.

    Args:
      world: an ``ambulo.sim.World`` of one world (``num_worlds=1``).
      cfg: topics, frames, rates, QoS (``BridgeCfg``).
      cmd_vel_handler: what turns /cmd_vel into actions (default: differential drive for a
        ``WheeledRobot``, the shipped walking policy for the bundled humanoid when the World steps
        at its physics_dt, 0.005 s; another free-floating robot refuses /cmd_vel saying why).
    """

    def __init__(self, world, cfg: BridgeCfg | None = None, *, cmd_vel_handler: CmdVelHandler | None = None):
        if world.engine is None:
            raise RuntimeError("the World has not been reset yet: call world.reset() before attaching a bridge")
        if world.num_worlds != 1:
            raise ValueError(f"a ROS 2 bridge serves one world; this World has num_worlds={world.num_worlds}")
        self.world, self.cfg = world, cfg or BridgeCfg()
        self.rclpy = import_rclpy()
        self.published: Counter = Counter()
        """topic -> messages published (the publisher process's counts, filled in by ``close()``)."""
        self.failed: Counter = Counter()
        """topic -> messages that rclpy refused to publish (filled in by ``close()``; normally empty)."""
        self.rejected: list[str] = []
        """Why each refused command was refused, in arrival order."""
        self.on_publish = None
        """Optional ``fn(topic, stamp_ns)`` called on the physics thread when a message's state is taken (the
        snapshot, or the image or scan handed to the publisher process); benchmarks time latency from it."""
        self._lock = threading.Lock()
        self._pending: dict[str, object] = {}
        self._previous_s, self._next_due_s = float("inf"), float("inf")
        """Simulated time of the last publishing pass, and the earliest time a topic is due again."""
        self.cmd_vel: tuple[float, float, float] | None = None
        """The velocity command being followed: (forward m/s, left m/s, yaw rate rad/s)."""
        self.walking = False
        """True while a walking policy (a handler with ``every_step``) drives the robot's joints: from
        attaching until a joint command, and again from the next accepted Twist."""
        self._warned_at: dict[str, float] = {}
        self._find_scene()
        self._handler = cmd_vel_handler
        if self._handler is None and self.robot is not None:
            self._handler = default_cmd_vel_handler(self.robot, world.get_physics_dt())
        self._every_step = bool(getattr(self._handler, "every_step", False))
        self.walking = self._every_step
        self.dropped = 0
        """Snapshots skipped because the publisher process was behind (``BridgeCfg.drop_when_behind``)."""
        self.dropped_frames = 0
        """Camera images skipped for the same reason."""
        self.subscribers: dict[str, tuple[int, float]] = {}
        """topic -> (matched subscriptions, ``time.time()`` when that count last changed), as the
        publisher's DDS writer saw it: a message published after that time reaches every one of them."""
        self._links = [link for r in self.robots for link in r.dynamic]
        self._base_frame = next((r.dynamic[0].child for r in self.robots if r.robot is self.robot), "")
        self._start_publisher()
        world.add_physics_callback("ros2_bridge", self._on_physics_step)
        self.closed = False

    # -- the scene ---------------------------------------------------------------------------
    def _find_scene(self) -> None:
        from ..sensors import Camera, Imu, Lidar  # noqa: PLC0415
        from ..sim import Articulation  # noqa: PLC0415

        cfg, model = self.cfg, self.world.model
        robots = [p for p in self.world.scene.prims() if isinstance(p, Articulation)]
        several = len(robots) > 1
        self.robots = [robot_frames(model, r, r.name, cfg.frame_prefix + (f"{r.name}/" if several else ""),
                                    cfg.frame_prefix + cfg.odom_frame, cfg.base_frame) for r in robots]
        names = [r.name for r in robots]
        if cfg.robot is not None and cfg.robot not in names:
            raise ValueError(f"BridgeCfg.robot={cfg.robot!r} is not a robot of the scene; robots: {names}")
        self.robot = next((r for r in robots if cfg.robot in (None, r.name)), None)
        self.joint_names = [(f"{r.name}/" if several else "") + j for r in robots for j in r.entity.joint_names]
        if self.robot is not None:
            known = list(self.robot.entity.joint_names)
            self.command_joints = list(cfg.command_joints) if cfg.command_joints is not None else known
            problem = names_problem(self.command_joints, known)
            if problem:
                raise ValueError(f"BridgeCfg.command_joints: {problem}")
        sensors = [getattr(c, "sensor", c) for c in self.world.sim.components.values()]
        self.imus = [s for s in sensors if isinstance(s, Imu)]
        self.cameras = [s for s in sensors if isinstance(s, Camera)]
        self.lidars = [s for s in sensors if isinstance(s, Lidar)]

    def _frame_of_body(self, body: int) -> str:
        for robot in self.robots:
            if body in robot.frame_of_body:
                return robot.frame_of_body[body]
        return self.cfg.frame_prefix + self.cfg.odom_frame

    def _sensor_frames(self) -> list:
        """Fixed frames of the IMUs, cameras (optical) and lidars in their mount bodies."""
        engine, model, prefix = self.world.engine, self.world.model, self.cfg.frame_prefix
        xpos, xmat = engine.field("xpos")[0].cpu().numpy(), engine.field("xmat")[0].cpu().numpy().reshape(-1, 3, 3)
        frames, self._sensor_frame = [], {}
        for imu in self.imus:
            site = model.site(imu.site_name).id
            body = int(model.site_bodyid[site])
            pos = engine.field("site_xpos")[0, site].cpu().numpy()
            rot = engine.field("site_xmat")[0, site].cpu().numpy().reshape(3, 3)
            frames.append(static_from_world(self._frame_of_body(body), prefix + leaf(imu.prim_path),
                                            xpos[body], xmat[body], pos, rot))
        for camera in self.cameras:
            body = camera._mount_pose.body_id
            pos, rot_gl = (a[0] for a in camera._pose_gl())
            frames.append(static_from_world(self._frame_of_body(body), prefix + leaf(camera.prim_path) + "_optical",
                                            xpos[body], xmat[body], pos, rot_gl @ OPTICAL_FROM_GL))
        for lidar in self.lidars:
            body = lidar._mount_pose.body_id
            mount_pos, mount_rot = (t[0].cpu().numpy() for t in (lidar._mount_pose.pos_w(), lidar._mount_pose.rot_w()))
            pos = mount_pos + mount_rot @ lidar._offset_m.cpu().numpy()
            rot = mount_rot @ lidar._rot_ms.cpu().numpy()
            frames.append(static_from_world(self._frame_of_body(body), prefix + leaf(lidar.prim_path),
                                            xpos[body], xmat[body], pos, rot))
        for sensor, frame in zip(self.imus + self.cameras + self.lidars, frames):
            self._sensor_frame[id(sensor)] = frame.child
        return frames

    # -- the publisher process -------------------------------------------------------------------
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

    def _views_of_slot(self, slot: int) -> tuple:
        """(index of the slot's first int64 in ``_header``, the copies to make: (destination, source)...)."""
        ring = self._ring
        return (HEADER_BYTES // 8 + slot * ring.layout.width,
                [(ring.block(slot, n), src) for n, src in self._sources.items() if n in ("qpos", "qvel", "qfrc")],
                [(ring.block(slot, n), src) for n, src in self._sources.items() if n in ("xpos", "xquat")],
                ring.block(slot, "sensordata") if "sensordata" in self._sources else None,
                ring.block(slot, "odom") if "odom" in ring.layout.blocks else None,
                {i: ring.block(slot, f"imu{i}") for i in range(len(self.imus)) if f"imu{i}" in ring.layout.blocks})

    def _send(self, msg) -> None:
        with self._send_lock:
            self._conn.send(msg)

    def _listen(self) -> None:
        """Commands from the publisher process (this thread checks them, as rclpy's executor did)."""
        while True:
            try:
                msg = self._conn.recv()
            except (EOFError, OSError):
                return
            try:
                if msg[0] == "twist":
                    self._on_twist(msg[1], msg[2])
                elif msg[0] == "joint_array":
                    self._on_joint_array(msg[1])
                elif msg[0] == "joint_state":
                    self._on_joint_state(msg[1], msg[2])
                elif msg[0] == "matched":  # (matched, topic, subscriptions now, wall time s)
                    self.subscribers[msg[1]] = (msg[2], msg[3])
                elif msg[0] == "closed":
                    self._closed_counts = msg[1]
                    self.failed.update(msg[2])
                    return
            except Exception as err:  # noqa: BLE001 - a command must never end the bridge
                log.error("ROS 2 command %s failed: %s", msg[0], err)

    @property
    def _last(self) -> dict[str, float]:
        """key (``clock``, ``imu0``, ``camera0``, ``lidar0``, ...) -> simulated time it was last due."""
        return {entry[1]: entry[3] for entry in self._schedule if entry[3] != -_INF}

    @property
    def topics(self) -> list[str]:
        """Names of the topics this bridge publishes."""
        return sorted(self._topic.values())

    @property
    def cmd_vel_problem(self) -> str | None:
        """Why every /cmd_vel is refused (no robot, no controller, no walking policy), or None."""
        if self.robot is None:
            return "the scene has no robot"
        if self._handler is None:
            return f"robot {self.robot.name!r} has no velocity controller"
        return getattr(self._handler, "problem", None)

    def warn(self, topic: str, problem: str) -> None:
        """Refuse a command: remember why, and log it (at most once a second per problem)."""
        text = f"{topic}: command rejected: {problem}"
        self.rejected.append(text)
        now = time.monotonic()
        if now - self._warned_at.get(text, -1e9) >= 1.0:
            self._warned_at[text] = now
            try:
                self._send(("warn", text))  # the node logs it: to the console and /rosout
            except OSError:
                log.warning(text)

    # -- commands (listener thread) --------------------------------------------------------------
    def _on_twist(self, lin, ang) -> None:
        handler = self._handler
        if handler is None:
            return self.warn(self.cfg.cmd_vel_topic, f"robot {self.robot.name!r} has no velocity controller")
        check = getattr(handler, "check", None)
        problem = getattr(handler, "problem", None) or (check(lin, ang) if check is not None else twist_problem(
            lin, ang, self.cfg.max_linear_speed_m_s, self.cfg.max_angular_speed_rad_s,
            getattr(handler, "holonomic", False)))
        if problem:
            return self.warn(self.cfg.cmd_vel_topic, problem)
        with self._lock:
            self._pending["cmd_vel"] = (float(lin[0]), float(lin[1]), float(ang[2]))
            self._pending["walking"] = True  # the latest of a Twist and a joint command decides

    def _on_joint_array(self, data) -> None:
        values = np.asarray(data, float)
        limits = self.robot.entity.joint_pos_limits.cpu().numpy()[self.robot.entity.find_joints(self.command_joints)]
        problem = targets_problem(values, self.command_joints, limits)
        if problem:
            return self.warn(self.cfg.joint_command_topic, problem)
        with self._lock:
            self._pending["joints"] = (list(self.command_joints), values)
            self._pending["walking"] = False

    def _on_joint_state(self, names, positions) -> None:
        names, values = list(names), np.asarray(positions, float)
        problem = names_problem(names, list(self.robot.entity.joint_names))
        if problem is None:
            limits = self.robot.entity.joint_pos_limits.cpu().numpy()[self.robot.entity.find_joints(names)]
            problem = targets_problem(values, names, limits)
        if problem:
            return self.warn(self.cfg.joint_state_command_topic, problem)
        with self._lock:
            self._pending["joints"] = (names, values)
            self._pending["walking"] = False

    def _apply_commands(self) -> None:
        from ..sim import ArticulationAction  # noqa: PLC0415

        if not self._pending and self.cmd_vel is None and not self.walking:  # nothing new, nothing to follow
            return
        with self._lock:
            pending, self._pending = self._pending, {}
            self.cmd_vel = pending.get("cmd_vel", self.cmd_vel)
        if self._every_step and "walking" in pending:
            if not pending["walking"]:  # a joint command pauses the walking policy until the next Twist
                hand_over = getattr(self._handler, "hand_over", None)
                if self.walking and hand_over is not None:
                    hand_over()
                self.cmd_vel = None
            self.walking = pending["walking"]
        if "joints" in pending:
            names, values = pending["joints"]
            idx = self.robot.entity.find_joints(names)
            self.robot.apply_action(ArticulationAction(joint_positions=values, joint_indices=idx))
        if self._handler is None or not (self.walking if self._every_step else self.cmd_vel is not None):
            return
        try:
            self._handler(self.cmd_vel or (0.0, 0.0, 0.0))  # a walking policy walks in place before a Twist
        except ValueError as err:
            self.cmd_vel, self.walking = None, False
            self.warn(self.cfg.cmd_vel_topic, str(err))


    # -- publishing (physics thread): a snapshot into the ring ------------------------------------
    def _on_physics_step(self, _dt: float) -> None:
        if self._pending or self.cmd_vel is not None or self.walking:
            self._apply_commands()
        now = self._now()
        if not self._previous_s <= now < self._next_due_s:  # else nothing is due (most steps at high
            self.publish_now(now)  # physics rates)

    def publish_now(self, now: float | None = None) -> None:
        """Snapshot every state topic that is due at the current simulated time (``now``, s) for the
        publisher process; render and send the cameras and lidars that are due."""
        if now is None:
            now = self._now()
        if self._previous_s <= now < self._next_due_s:  # the common case at high physics rates
            return
        flags, others, soonest = 0, None, _INF
        # ambulo.sim.base_sensor.due() per topic, inlined, with each topic's next due time cached:
        # [bit (0: a camera or lidar), key, period s, last s, next due s]
        for entry in self._schedule:
            last = entry[3]
            if now >= entry[4] or now < last:
                period = entry[2]
                if now != last if period <= 0.0 else (now < last or last == -_INF or math.floor(
                        now / period + 1e-9) != math.floor(last / period + 1e-9)):
                    entry[3] = last = now
                    if entry[0]:
                        flags |= entry[0]
                    else:
                        others = [*(others or ()), entry[1]]
                entry[4] = math.nextafter(last, _INF) if period <= 0.0 else \
                    (math.floor(last / period + 1e-9) + 1 - 1e-9) * period
            if entry[4] < soonest:
                soonest = entry[4]
        self._previous_s, self._next_due_s = now, soonest
        ns = round(now * 1e9)
        if flags:
            self._snapshot(flags, ns)
        if others:
            for key in others:
                i = int(key[6:]) if key.startswith("camera") else int(key[5:])
                if key.startswith("camera"):
                    self._publish_camera(i, self.cameras[i], now, ns)
                else:
                    self._publish(key, self._serialize(self._lidar_msg(self.lidars[i], now)), ns)

    def _snapshot(self, flags: int, ns: int) -> None:
        """Copy what the due topics need into the next free slot (the only publishing work on the
        physics thread: a few NumPy copies)."""
        header, slots = self._header, self._slots
        written = header[WRITTEN]
        if written - self._read_seen >= slots:  # READ is the other core's line: loaded only when the
            self._read_seen = header[READ]  # ring looked full at the last value seen
        if written - self._read_seen >= slots:
            if self.cfg.drop_when_behind:
                self.dropped += 1
                return
            while written - header[READ] >= slots:  # the publisher is behind: wait for a free slot
                if self._proc.poll() is not None:
                    raise RuntimeError("the ROS 2 publisher process has exited")
                os.sched_yield()  # (time.sleep would oversleep by the timer slack, 50 us)
            self._read_seen = header[READ]
        start, joints, bodies, sensordata, odom, imus = self._slot_views[written % slots]
        header[start], header[start + 1] = ns, flags
        if self._staged:
            for stage, get in self._staged:
                np.copyto(stage, get())
        if flags & (JOINT_STATES | ODOM):
            for dst, src in joints:
                np.copyto(dst, src)
        if flags & TF:
            for dst, src in bodies:
                np.copyto(dst, src)
        if flags >= ODOM:
            self._snapshot_rest(flags, sensordata, odom, imus)
        header[WRITTEN] = written + 1
        _FENCE.acquire()  # a full barrier (fence()): the store above before the load below (the
        _FENCE.release()  # publisher process does the converse)
        if header[WAITING]:  # the publisher process sleeps or is about to: wake it (once: clearing the
            header[WAITING] = 0  # flag before the write cannot hide a later sleep, which the byte ends)
            try:
                os.write(self._wake_w, b"\0")
            except BlockingIOError:  # the pipe is full of wake-ups already
                pass
        if self.on_publish is not None:
            for bit, key, *_ in self._schedule:
                if flags & bit:
                    self.on_publish(self._topic[key], ns)

    def _snapshot_rest(self, flags: int, sensordata, odom, imus) -> None:
        if flags & ODOM and odom is not None:
            d = self.robot.entity.data
            odom[:] = np.concatenate([d.root_pos_w[0].cpu().numpy(), xyzw(d.root_quat_w[0].cpu().numpy()), np.zeros(36),
                                      d.root_lin_vel_b[0].cpu().numpy(), d.root_ang_vel_b[0].cpu().numpy(),
                                      np.zeros(36)])
        if flags >= IMU0:
            for i, imu in enumerate(self.imus):
                if flags & (IMU0 << i):
                    if self._imu_fast[i]:
                        np.copyto(sensordata, self._sources["sensordata"])
                    else:
                        imus[i][:] = self._imu_values(imu)

    def _publish(self, key: str, data: bytes, stamp_ns: int) -> None:
        """Send one message built here (images, camera info, lidar) to the publisher process, which
        publishes it after the snapshots taken before it."""
        if self.on_publish is not None:
            self.on_publish(self._topic[key], stamp_ns)
        self._send(("raw", key, data, stamp_ns, self._header[WRITTEN]))

    def publish_costmap(self, costmap, topic: str = "costmap", frame_id: str | None = None) -> None:
        """Publish an ``ambulo.perception.Costmap`` as ``nav_msgs/OccupancyGrid`` on ``topic`` (reliable,
        transient-local, keep-last 1: Nav2's map QoS, so a late rviz2 or planner still gets the latest),
        stamped with the simulated time, in ``frame_id`` (default: the fixed frame, ``odom``)."""
        key = f"grid:{topic}"
        if key not in self._topic:
            self._send(("advertise", key, "nav_msgs/msg/OccupancyGrid", topic, "static"))
            self._topic[key] = topic if topic.startswith("/") else f"{self.cfg.namespace.rstrip('/')}/{topic}"
        now = self.world.current_time
        frame = frame_id if frame_id is not None else self.cfg.frame_prefix + self.cfg.odom_frame
        self._publish(key, self._serialize(m.occupancy_grid(now, frame, costmap)), round(now * 1e9))

    def _publish_frame(self, key: str, ns: int, frame_id: str, encoding: str, pixels: np.ndarray) -> None:
        """An Image through the shared-memory frame ring: written once, the slot number sent after the
        snapshots taken before it. A full ring waits (lossless) or skips the frame (``drop_when_behind``)."""
        height, width = pixels.shape[:2]
        prefix = cdr.image_prefix(ns, frame_id, height, width, encoding, pixels.nbytes // height, pixels.nbytes)
        nbytes = self._frames.put(prefix, pixels)
        while nbytes is None:
            if self.cfg.drop_when_behind:
                self.dropped_frames += 1
                return
            if self._proc.poll() is not None:
                raise RuntimeError("the ROS 2 publisher process has exited")
            time.sleep(0.0002)  # a frame takes the publisher ~1 ms: no point spinning
            nbytes = self._frames.put(prefix, pixels)
        if self.on_publish is not None:
            self.on_publish(self._topic[key], ns)
        self._send(("frame", key, nbytes, ns, self._header[WRITTEN]))

    def _imu_values(self, imu) -> np.ndarray:
        """The 37 Imu values of a noisy IMU (or one with gravity removed): its noise model runs here."""
        noise = imu.cfg.noise
        if any((noise.gyro_noise_density, noise.accel_noise_density, noise.gyro_random_walk, noise.accel_random_walk,
                noise.gyro_turn_on_bias_std, noise.accel_turn_on_bias_std)):
            data = imu.get_current_frame()
            acc, gyro, quat = data.lin_acc_b, data.ang_vel_b, data.quat_w
        else:  # noiseless: the engine's reading as it is (no noise model to advance)
            acc, gyro, quat = imu.clean_reading()
        rate = 1.0 / (imu.update_period_s or self.world.get_physics_dt())
        # white noise of density sigma_c (unit/sqrt(Hz)) sampled at rate f has variance sigma_c^2 f
        gyro_var, acc_var = noise.gyro_noise_density ** 2 * rate, noise.accel_noise_density ** 2 * rate
        return np.concatenate([xyzw(quat[0].cpu().numpy()), np.zeros(9), gyro[0].cpu().numpy(),
                               np.diag([gyro_var] * 3).ravel(), acc[0].cpu().numpy(), np.diag([acc_var] * 3).ravel()])

    def _publish_camera(self, i: int, camera, now: float, ns: int) -> None:
        wanted = ("rgb", "depth") if self.cfg.publish_depth else ("rgb",)
        out = camera.capture(0, annotators=wanted)
        frame = self._sensor_frame[id(camera)]
        rgb = np.ascontiguousarray(out["rgb"][..., :3])
        height, width = rgb.shape[:2]
        self._publish_frame(f"rgb{i}", ns, frame, "rgb8", rgb)
        if self.cfg.publish_depth:  # REP 118: 32FC1, metres along the optical axis
            self._publish_frame(f"depth{i}", ns, frame, "32FC1", np.ascontiguousarray(out["depth"], "<f4"))
        cam = out["camera"]
        self._publish(f"info{i}", self._serialize(m.camera_info(now, frame, cam["width"], cam["height"],
                                                                cam["intrinsics"])), ns)

    def _lidar_msg(self, lidar, now: float):
        data, frame = lidar.get_current_frame(), self._sensor_frame[id(lidar)]
        if lidar.shape[0] == 1:
            return m.laser_scan(now, frame, lidar.azimuths_rad, data.ranges[0, 0].cpu().numpy(), lidar.cfg.min_range_m,
                                lidar.cfg.max_range_m, lidar.update_period_s or 1.0 / self.cfg.lidar_rate_hz)
        points = data.points_s[0][data.hit[0].reshape(-1)].cpu().numpy()
        return m.point_cloud(now, frame, points)

    # -- teardown -------------------------------------------------------------------------------
    def close(self) -> None:
        """Stop publishing, leave the ROS graph and finish the bag (the publisher process publishes
        every snapshot taken so far first); the World keeps running. ``published`` then holds the
        publisher process's counts."""
        if getattr(self, "closed", True):
            return
        self.closed = True
        if self.world.physics_callback_exists("ros2_bridge"):
            self.world.remove_physics_callback("ros2_bridge")
        try:
            self._send(("close",))
        except OSError:
            pass
        self._listener.join(timeout=60.0)
        try:
            self._proc.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
        if self._closed_counts is not None:
            self.published.update(self._closed_counts)
        self._conn.close()
        os.close(self._wake_w)
        self._slot_views = []
        self._header.release()
        self._ring.close()
        if self._frames is not None:
            self._frames.close()

    def __enter__(self) -> Ros2Bridge:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


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


def attach_bridge(world, cfg: BridgeCfg | None = None, **kwargs) -> Ros2Bridge:
    """``Ros2Bridge(world, cfg, **kwargs)``: the World becomes a ROS 2 node until ``close()``."""
    return Ros2Bridge(world, cfg, **kwargs)


__all__ = ["Ros2Bridge", "attach_bridge"]
