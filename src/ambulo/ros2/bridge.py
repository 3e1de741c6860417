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

The bridge's parts, one purpose a file, each a mixin of ``Ros2Bridge`` (so that the physics-thread
path stays calls on the bridge itself): ``bridge_scene.py`` finds the robots, sensors and frames,
``bridge_launch.py`` starts the publisher process, ``bridge_publishing.py`` publishes on the physics
thread (the rate schedule and the ring snapshots) and ``bridge_commands.py`` takes commands.
"""

from __future__ import annotations

import os
import subprocess
import threading
from collections import Counter

from . import messages as m
from .bridge_commands import CommandIntake
from .bridge_launch import PublisherLaunch
from .bridge_publishing import PhysicsPublishing
from .bridge_scene import SceneDiscovery
from .commands import CmdVelHandler, default_cmd_vel_handler
from .config import BridgeCfg
from .runtime import import_rclpy


class Ros2Bridge(SceneDiscovery, PublisherLaunch, PhysicsPublishing, CommandIntake):
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

    # -- what it publishes, and why /cmd_vel would be refused -------------------------------------
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


def attach_bridge(world, cfg: BridgeCfg | None = None, **kwargs) -> Ros2Bridge:
    """``Ros2Bridge(world, cfg, **kwargs)``: the World becomes a ROS 2 node until ``close()``."""
    return Ros2Bridge(world, cfg, **kwargs)


__all__ = ["Ros2Bridge", "attach_bridge"]
