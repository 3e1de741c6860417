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

The bridge owns four parts, one purpose a file: ``scene`` (``bridge_scene.SceneDiscovery``: the robots,
sensors and frames), ``process`` (``bridge_launch.PublisherProcess``: the node's process, started from
the spec ``bridge_launch`` builds), ``publishing`` (``bridge_publishing.PhysicsPublisher``: the rate
schedule and the ring snapshots, on the physics thread; its detector's ``bridge_detection.DetectionWorker``
on a thread of its own) and ``commands``
(``bridge_commands.CommandIntake``: checks commands on the listener thread, applies them on the
physics thread).
"""

from __future__ import annotations

from collections import Counter

from .bridge_commands import CommandIntake
from .bridge_launch import (
    PublisherProcess,
    close_at_exit,
    frame_slot_bytes,
    publisher_spec,
    snapshot_sources,
    static_messages,
    time_source,
)
from .bridge_publishing import PhysicsPublisher, check_detector
from .bridge_scene import SceneDiscovery
from .commands import CmdVelHandler, default_cmd_vel_handler
from .config import BridgeCfg
from .runtime import import_rclpy, use_fastdds_profile


class Ros2Bridge:
    """Attach a ROS 2 node to ``world`` (already ``reset()``); ``close()`` (or ``with``) detaches it.

    Args:
      world: an ``ambulo.sim.World`` of one world (``num_worlds=1``).
      cfg: topics, frames, rates, QoS (``BridgeCfg``).
      cmd_vel_handler: what turns /cmd_vel into actions (default: differential drive for a
        ``WheeledRobot``, the shipped walking policy for the bundled humanoid when the World steps
        at its physics_dt, ``robots.humanoid.POLICY_PHYSICS_DT_S``; another free-floating robot
        refuses /cmd_vel saying why).
      detector: an ``ambulo.detection.Detector`` (any callable of an (H, W, 3) uint8 frame returning
        ``boxes_px``, ``labels``, ``scores``, ``masks``, with ``canvas_hw``), run on the published camera
        frames on a thread of its own (``bridge_detection.DetectionWorker``; the newest frame of each camera
        when it is slower than the camera rate, the others counted in ``dropped_detections``), or on every
        frame on the physics thread (``BridgeCfg.detector_thread=False``): ``detections``
        (vision_msgs/msg/Detection2DArray) and, for a model with masks, ``detections/segmentation`` (mono16
        instances) and ``detections/semantic`` (mono8 category ids, 0 background), stamped and framed like the
        image they were computed on. A camera larger than its canvas is a ``ValueError``; an exception of the
        detector is raised as ``bridge_detection.DetectorFailed`` on the next physics step (or by ``close``).
    """

    def __init__(self, world, cfg: BridgeCfg | None = None, *, cmd_vel_handler: CmdVelHandler | None = None,
                 detector=None):
        if world.engine is None:
            raise RuntimeError("the World has not been reset yet: call world.reset() before attaching a bridge")
        if world.num_worlds != 1:
            raise ValueError(f"a ROS 2 bridge serves one world; this World has num_worlds={world.num_worlds}")
        self.world, self.cfg = world, cfg or BridgeCfg()
        self.rclpy = import_rclpy()
        from rclpy.serialization import serialize_message  # after import_rclpy finds it

        self.published: Counter = Counter()
        """topic -> messages published (the publisher process's counts, filled in by ``close()``)."""
        self.closed = True  # until the publisher process runs
        self.scene = SceneDiscovery(world, self.cfg)
        scene = self.scene
        self.robots, self.robot, self.joint_names = scene.robots, scene.robot, scene.joint_names
        self.command_joints, self.imus, self.cameras, self.lidars = (scene.command_joints, scene.imus, scene.cameras,
                                                                      scene.lidars)
        handler = cmd_vel_handler
        if handler is None and self.robot is not None:
            handler = default_cmd_vel_handler(self.robot, world.get_physics_dt())
        self.commands = CommandIntake(self.cfg, self.robot, self.command_joints, handler, self._send)
        if detector is not None:
            check_detector(detector, scene.cameras)
        snapshot = snapshot_sources(world, self.cfg, scene)
        static, self.urdf = static_messages(world, self.cfg, scene, serialize_message)
        """``urdf``: the robot_description published (None without robots)."""
        if self.cfg.fastdds_profile:
            use_fastdds_profile()  # in the environment the publisher process inherits
        self.process = PublisherProcess(publisher_spec(self.cfg, scene, snapshot, static), frame_slot_bytes(scene),
                                        self.cfg, on_command=self.commands.receive)
        self.node_name, self.foxglove = self.process.node_name, self.process.foxglove
        """``node_name``: the node's fully qualified name (it lives in the publisher process)."""
        self.failed: Counter = self.process.failed
        """topic -> messages that rclpy refused to publish (filled in by ``close()``; normally empty)."""
        self.subscribers: dict[str, tuple[int, float]] = self.process.subscribers
        """topic -> (matched subscriptions, ``time.time()`` when that count last changed), as the
        publisher's DDS writer saw it: a message published after that time reaches every one of them."""
        self.publishing = PhysicsPublisher(world, self.cfg, scene, self.process, snapshot, serialize_message,
                                           time_source(world), detector)
        self.closed = False
        close_at_exit(self)  # an exception ending the program still closes the publisher process cleanly
        world.add_physics_callback("ros2_bridge", self._on_physics_step)

    # -- the physics thread ---------------------------------------------------------------------
    def _on_physics_step(self, _dt: float) -> None:
        commands = self.commands
        if commands.pending or commands.cmd_vel is not None or commands.walking:
            commands.apply()
        self.publishing.step()

    def publish_now(self, now: float | None = None) -> None:
        """Snapshot every state topic that is due at the current simulated time (``now``, s) for the
        publisher process; render and send the cameras and lidars that are due."""
        self.publishing.publish_now(now)

    def _send(self, msg) -> None:
        self.process.send(msg)

    # -- what it publishes, what it follows, and why /cmd_vel would be refused ----------------------
    @property
    def topics(self) -> list[str]:
        """Names of the topics this bridge publishes."""
        return sorted(self.process.topic.values())

    @property
    def cmd_vel(self) -> tuple[float, float, float] | None:
        """The velocity command being followed: (forward m/s, left m/s, yaw rate rad/s)."""
        return self.commands.cmd_vel

    @property
    def walking(self) -> bool:
        """True while a walking policy (a handler with ``every_step``) drives the robot's joints: from
        attaching until a joint command, and again from the next accepted Twist."""
        return self.commands.walking

    @property
    def rejected(self) -> list[str]:
        """Why each refused command was refused, in arrival order."""
        return self.commands.rejected

    def warn(self, topic: str, problem: str) -> None:
        """Refuse a command: remember why, and log it (at most once a second per problem)."""
        self.commands.warn(topic, problem)

    @property
    def dropped(self) -> int:
        """Snapshots skipped because the publisher process was behind (``BridgeCfg.drop_when_behind``)."""
        return self.publishing.dropped

    @property
    def dropped_frames(self) -> int:
        """Camera images skipped for the same reason."""
        return self.publishing.dropped_frames

    @property
    def dropped_detections(self) -> int:
        """Camera frames the detector's thread skipped: replaced by a newer frame of the same camera while the
        detector worked on an earlier one (always 0 with ``BridgeCfg.detector_thread=False``)."""
        return self.publishing.dropped_detections

    @property
    def on_publish(self):
        """Optional ``fn(topic, stamp_ns)`` called when a message's state is taken (the snapshot, or the image
        or scan handed to the publisher process); benchmarks time latency from it. Called on the physics
        thread, and for a detector's topics on its thread, one call at a time (under a lock)."""
        return self.publishing.on_publish

    @on_publish.setter
    def on_publish(self, fn) -> None:
        self.publishing.on_publish = fn

    @property
    def cmd_vel_problem(self) -> str | None:
        """Why every /cmd_vel is refused (no robot, no controller, no walking policy), or None."""
        if self.robot is None:
            return "the scene has no robot"
        if self.commands.handler is None:
            return f"robot {self.robot.name!r} has no velocity controller"
        return getattr(self.commands.handler, "problem", None)

    def publish_costmap(self, costmap, topic: str = "costmap", frame_id: str | None = None) -> None:
        """Publish an ``ambulo.perception.Costmap`` as ``nav_msgs/OccupancyGrid`` on ``topic`` (reliable,
        transient-local, keep-last 1: Nav2's map QoS, so a late rviz2 or planner still gets the latest),
        stamped with the simulated time, in ``frame_id`` (default: the fixed frame, ``odom``)."""
        self.publishing.publish_costmap(costmap, topic, frame_id)

    # -- teardown -------------------------------------------------------------------------------
    def close(self) -> None:
        """Stop publishing, leave the ROS graph and finish the bag (the publisher process publishes
        every snapshot taken so far first); the World keeps running. ``published`` then holds the
        publisher process's counts. The detector's pending frames are detected and published first; its
        exception, if no physics step raised it yet, is raised after everything is closed."""
        if getattr(self, "closed", True):
            return
        self.closed = True
        if self.world.physics_callback_exists("ros2_bridge"):
            self.world.remove_physics_callback("ros2_bridge")
        try:
            self.publishing.close_detection()
        finally:
            self.publishing.release()
            self.process.close()
            if self.process.published is not None:
                self.published.update(self.process.published)

    def __enter__(self) -> Ros2Bridge:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def attach_bridge(world, cfg: BridgeCfg | None = None, **kwargs) -> Ros2Bridge:
    """``Ros2Bridge(world, cfg, **kwargs)``: the World becomes a ROS 2 node until ``close()``."""
    return Ros2Bridge(world, cfg, **kwargs)


__all__ = ["Ros2Bridge", "attach_bridge"]
