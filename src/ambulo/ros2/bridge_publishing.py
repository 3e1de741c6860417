"""``PhysicsPublisher``: a ``Ros2Bridge``'s publishing on the physics thread.

Before each physics step (``step``) the rate schedule says which topics are due at the simulated time;
the state topics' arrays are copied into the next free slot of the shared-memory ring (``_snapshot``:
the only publishing work on the physics thread for them), and the cameras' images (through the frame
ring) and the lidars' messages are handed to the publisher process. The step path is timed in
microseconds: it is plain attribute reads and NumPy copies, no per-topic objects.

A detector's frames go to a ``bridge_detection.DetectionWorker`` (its own thread unless
``BridgeCfg.detector_thread`` is False), which publishes from that thread too. Two threads then send:
``process.send`` has its own lock; the frame ring (slots used in order, each slot's number sent after it is
written, so writing a slot and sending its number must not interleave with the other thread's) and
``on_publish`` callbacks (user code, not thread-safe in general) go under ``_out_lock``, held only for a
copy and a send, never for an inference.
"""

from __future__ import annotations

import math
import os
import threading
import time

import numpy as np

from . import cdr
from . import messages as m
from .bridge_detection import DetectionJob, DetectionWorker, owned
from .bridge_launch import SnapshotSources, imu_is_clean, state_topics
from .frames import leaf, xyzw
from .ring import _FENCE, HEADER_BYTES, IMU0, JOINT_STATES, ODOM, READ, TF, WAITING, WRITTEN

_INF = float("inf")


def check_detector(detector, cameras) -> None:
    """``ValueError`` naming the fix when a camera's frames are larger than ``detector``'s canvas (before
    the publisher process starts); a scene without cameras has nothing to detect on."""
    from .detections import detections_fit

    if not cameras:
        raise ValueError("a detector needs a camera, and the scene has none; leave out --no-camera (or the "
                         "detector)")
    for camera in cameras:
        problem = detections_fit(detector.canvas_hw, *camera.resolution, f"camera {camera.prim_path!r}")
        if problem:
            raise ValueError(problem)


class PhysicsPublisher:
    """The physics-thread side of a bridge: the schedule, ``publish_now``, the ring snapshots and the
    camera, lidar and other messages sent to ``process`` (a ``bridge_launch.PublisherProcess``).

    Attributes: ``dropped`` and ``dropped_frames`` (snapshots and images skipped while the process was
    behind, ``BridgeCfg.drop_when_behind``), ``on_publish`` (optional ``fn(topic, stamp_ns)`` called
    when a message's state is taken, from the physics thread or the detection worker's, never both at once),
    ``last`` (key -> simulated time it was last due), ``detection`` (the ``DetectionWorker``, or None).
    """

    def __init__(self, world, cfg, scene, process, snapshot: SnapshotSources, serialize, now, detector=None):
        self.world, self.cfg, self.scene, self.process = world, cfg, scene, process
        self.robot, self.imus, self.cameras, self.lidars = scene.robot, scene.imus, scene.cameras, scene.lidars
        self._serialize, self._now = serialize, now
        self._header, self._ring, self._topic = process.header, process.ring, process.topic
        self._proc, self._wake_w, self._frames = process.proc, process.wake_w, process.frames
        self._sources, self._staged, self._imu_fast = snapshot.sources, snapshot.staged, snapshot.imu_fast
        self._slots = snapshot.layout.slots
        self._slot_views = [self._views_of_slot(s) for s in range(self._slots)]
        self._read_seen = 0
        """The publisher's ``READ`` counter as last loaded (it only grows, so a stale value is safe)."""
        # [bit (0: a camera or lidar), key, period s, last s, next due s]
        self._schedule = [[bit, key, 0.0 if rate is None else 1.0 / rate, -_INF, -_INF]
                          for bit, key, rate in state_topics(scene, cfg)]
        self._schedule += [[0, f"camera{i}", 1.0 / cfg.camera_rate_hz, -_INF, -_INF] for i in range(len(self.cameras))]
        self._schedule += [[0, f"lidar{i}", 1.0 / cfg.lidar_rate_hz, -_INF, -_INF] for i in range(len(self.lidars))]
        self._previous_s, self._next_due_s = _INF, _INF
        """Simulated time of the last publishing pass, and the earliest time a topic is due again."""
        self.dropped = 0
        self.dropped_frames = 0
        self.on_publish = None
        self._out_lock = threading.Lock()
        """Held while a frame ring slot is written and its number sent, and around ``on_publish`` calls."""
        self.detector = detector
        self.detection = None
        if detector is not None:
            self._advertise_detections()
            self.detection = DetectionWorker(self._detect_and_publish, len(self.cameras), cfg.detector_thread)

    # -- the step path: the rate schedule, then a snapshot into the ring --------------------------
    def step(self) -> None:
        """Before a physics step: publish what is due at the simulated time (most steps: nothing)."""
        now = self._now()
        if not self._previous_s <= now < self._next_due_s:
            self.publish_now(now)
        if self.detection is not None and self.detection.error is not None:
            self.detection.check()  # the detector's exception, raised once on the physics thread

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
            with self._out_lock:
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
        with self._out_lock:
            if self.on_publish is not None:
                self.on_publish(self._topic[key], stamp_ns)
            self.process.send(("raw", key, data, stamp_ns, self._header[WRITTEN]))

    # -- cameras, IMUs and lidars ----------------------------------------------------------------
    def _publish_frame(self, key: str, ns: int, frame_id: str, encoding: str, pixels: np.ndarray) -> None:
        """An Image through the shared-memory frame ring: written once, the slot number sent after the
        snapshots taken before it. A full ring waits (lossless) or skips the frame (``drop_when_behind``).
        Called from the physics thread and the detection worker: the slot's write and the send of its number
        are one step under ``_out_lock`` (the publisher reads slots in the order their numbers arrive)."""
        height, width = pixels.shape[:2]
        prefix = cdr.image_prefix(ns, frame_id, height, width, encoding, pixels.nbytes // height, pixels.nbytes)
        while True:
            with self._out_lock:
                nbytes = self._frames.put(prefix, pixels)
                if nbytes is not None:
                    if self.on_publish is not None:
                        self.on_publish(self._topic[key], ns)
                    self.process.send(("frame", key, nbytes, ns, self._header[WRITTEN]))
                    return
                if self.cfg.drop_when_behind:
                    self.dropped_frames += 1
                    return
            if self._proc.poll() is not None:
                raise RuntimeError("the ROS 2 publisher process has exited")
            time.sleep(0.0002)  # a frame takes the publisher ~1 ms: no point spinning (the lock is free meanwhile)

    def _imu_values(self, imu) -> np.ndarray:
        """The 37 Imu values of a noisy IMU (or one with gravity removed): its noise model runs here."""
        noise = imu.cfg.noise
        if not imu_is_clean(imu):
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
        # an RGB-D detector (Detector.needs_depth) takes the same camera's depth with each frame, an RGB-D-height
        # one (needs_height) also each pixel's height above the floor, from that depth and the camera's pose
        detector_depth = self.detector is not None and getattr(self.detector, "needs_depth", False)
        detector_height = detector_depth and getattr(self.detector, "needs_height", False)
        wanted = ("rgb", "depth") if self.cfg.publish_depth or detector_depth else ("rgb",)
        out = camera.capture(0, annotators=wanted)
        frame = self.scene.sensor_frame[id(camera)]
        rgb = np.ascontiguousarray(out["rgb"][..., :3])
        self._publish_frame(f"rgb{i}", ns, frame, "rgb8", rgb)
        if self.detection is not None:  # the capture's arrays are fresh: the worker takes them without a copy
            self.detection.submit(DetectionJob(i, owned(rgb), owned(out["depth"]) if detector_depth else None,
                                               out["camera"] if detector_height else None, now, ns, frame))
        if self.cfg.publish_depth:  # REP 118: 32FC1, metres along the optical axis
            self._publish_frame(f"depth{i}", ns, frame, "32FC1", np.ascontiguousarray(out["depth"], "<f4"))
        cam = out["camera"]
        self._publish(f"info{i}", self._serialize(m.camera_info(now, frame, cam["width"], cam["height"],
                                                                cam["intrinsics"])), ns)

    def _advertise_detections(self) -> None:
        """Topics of ``detector``'s output for each camera: ``detections`` (one camera) or
        ``detections/<camera>``, and ``<that>/segmentation`` and ``<that>/semantic``."""
        from .detections import DETECTION_ARRAY, register_vision_msgs

        register_vision_msgs()  # here, once: the typestore is not filled from two threads
        for i, camera in enumerate(self.cameras):
            topic = "detections" if len(self.cameras) == 1 else f"detections/{leaf(camera.prim_path)}"
            self._advertise(f"det{i}", DETECTION_ARRAY, topic, "data")
            self._advertise(f"seg{i}", "sensor_msgs/msg/Image", f"{topic}/segmentation", "camera")
            self._advertise(f"sem{i}", "sensor_msgs/msg/Image", f"{topic}/semantic", "camera")

    def _advertise(self, key: str, typename: str, topic: str, kind: str) -> None:
        """A publisher added after the process started (QoS ``kind``: data, camera, static)."""
        if key not in self._topic:
            self.process.send(("advertise", key, typename, topic, kind))
            self._topic[key] = topic if topic.startswith("/") else f"{self.cfg.namespace.rstrip('/')}/{topic}"

    def _detect_and_publish(self, job: DetectionJob) -> None:
        """The detector on camera ``job.camera``'s frame (and its depth (H, W) m, for an RGB-D detector; and its
        height above the floor (H, W) m, for an RGB-D-height one, computed here from the depth and the camera's
        pose), on the detection worker's thread (or the physics thread, ``BridgeCfg.detector_thread=False``),
        published stamped and framed like the image it was computed on."""
        from .detections import detection_array_cdr, segmentation_of, semantic_of

        i, rgb, now, ns, frame = job.camera, job.rgb, job.time_s, job.stamp_ns, job.frame_id
        extra = ()
        if job.depth_m is not None:
            extra = (job.depth_m,)
            if job.camera_info is not None:
                from ambulo.sensors.floor_height import height_above_floor_m

                cam = job.camera_info
                extra += (height_above_floor_m(np.asarray(job.depth_m).reshape(rgb.shape[:2]), cam["intrinsics"],
                                               cam["extrinsics_cw"]),)
        found = self.detector(rgb, *extra)
        self._publish(f"det{i}", detection_array_cdr(now, frame, found.boxes_px, found.labels, found.scores), ns)
        image = segmentation_of(found)
        if image is not None:
            self._publish_frame(f"seg{i}", ns, frame, "mono16", np.ascontiguousarray(image, "<u2"))
        semantic = semantic_of(found)
        if semantic is not None:
            self._publish_frame(f"sem{i}", ns, frame, "mono8", np.ascontiguousarray(semantic, np.uint8))

    def _lidar_msg(self, lidar, now: float):
        data, frame = lidar.get_current_frame(), self.scene.sensor_frame[id(lidar)]
        if lidar.shape[0] == 1:
            return m.laser_scan(now, frame, lidar.azimuths_rad, data.ranges[0, 0].cpu().numpy(), lidar.cfg.min_range_m,
                                lidar.cfg.max_range_m, lidar.update_period_s or 1.0 / self.cfg.lidar_rate_hz)
        points = data.points_s[0][data.hit[0].reshape(-1)].cpu().numpy()
        return m.point_cloud(now, frame, points)

    # -- the ring views and the schedule ---------------------------------------------------------
    def _views_of_slot(self, slot: int) -> tuple:
        """(index of the slot's first int64 in ``_header``, the copies to make: (destination, source)...)."""
        ring = self._ring
        return (HEADER_BYTES // 8 + slot * ring.layout.width,
                [(ring.block(slot, n), src) for n, src in self._sources.items() if n in ("qpos", "qvel", "qfrc")],
                [(ring.block(slot, n), src) for n, src in self._sources.items() if n in ("xpos", "xquat")],
                ring.block(slot, "sensordata") if "sensordata" in self._sources else None,
                ring.block(slot, "odom") if "odom" in ring.layout.blocks else None,
                {i: ring.block(slot, f"imu{i}") for i in range(len(self.imus)) if f"imu{i}" in ring.layout.blocks})

    @property
    def last(self) -> dict[str, float]:
        """key (``clock``, ``imu0``, ``camera0``, ``lidar0``, ...) -> simulated time it was last due."""
        return {entry[1]: entry[3] for entry in self._schedule if entry[3] != -_INF}

    @property
    def dropped_detections(self) -> int:
        """Camera frames the detector skipped: replaced in their camera's slot by a newer frame while it worked."""
        return 0 if self.detection is None else self.detection.dropped

    def close_detection(self) -> None:
        """Detect and publish the pending frames and stop the detection worker (before the process closes);
        raises the detector's exception if no step raised it yet."""
        if self.detection is not None:
            self.detection.close()

    def release(self) -> None:
        """Drop the views into the ring, so the process can unmap it (the bridge is closing)."""
        self._slot_views = []

    def publish_costmap(self, costmap, topic: str, frame_id: str | None) -> None:
        """``Ros2Bridge.publish_costmap``: advertise ``topic`` once (Nav2's map QoS), then publish."""
        key = f"grid:{topic}"
        self._advertise(key, "nav_msgs/msg/OccupancyGrid", topic, "static")
        now = self.world.current_time
        frame = frame_id if frame_id is not None else self.cfg.frame_prefix + self.cfg.odom_frame
        self._publish(key, self._serialize(m.occupancy_grid(now, frame, costmap)), round(now * 1e9))


__all__ = ["PhysicsPublisher", "check_detector"]
