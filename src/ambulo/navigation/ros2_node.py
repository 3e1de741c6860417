"""``NavigateNode``: a ``Navigator`` as a real ROS 2 node (rclpy): goals in, the navigator's state out.

    world = NavWorld.from_apartment(3, start_pose)
    node = NavigateNode(Navigator(world, NavigatorCfg(mode="full")))
    node.spin()          # steps the navigator in simulated time until Ctrl-C (or ``seconds``)

In: ``/goal_pose`` (``geometry_msgs/PoseStamped``, what RViz's "2D Goal Pose" tool sends) in the
``map`` frame (``odom`` is accepted too: map -> odom is the identity, below). A goal replaces the
one being walked to; after a fall the navigator is reset first (``Navigator.reset``: the walker's
default pose, where the robot lies; the map and plans forgotten). A goal in another
frame, or not finite, is refused: a warning and ``rejected: <why>`` on the status topic.

Out, stamped with simulated time (``/clock`` as the bridge publishes it: every physics step, or at
``clock_rate_hz``):

- ``/plan`` (``nav_msgs/Path``): the route to the goal, at every replan that changed it;
- ``/footsteps`` (``visualization_msgs/MarkerArray``): a DELETEALL, then one CUBE per foot of the
  plan (left green, right red), at every replan that changed it;
- ``/map`` (``nav_msgs/OccupancyGrid``, the navigator's occupancy) and ``/costmap`` (its humanoid
  costmap, Nav2's cost translation), reliable and transient-local (Nav2's map QoS), ``map_rate_hz``;
- ``/odom`` (``nav_msgs/Odometry``, odom -> base_link) and ``/tf``: map -> odom -> base_link at
  the navigator's camera rate. odom -> base_link is the navigator's pose estimate (the VO's in
  ``full`` mode, ground truth otherwise) and map -> odom is the **identity**: the navigator's map
  is built at its own estimates (in ``full`` mode from VO poses), so the estimate is the robot's
  pose in that map and no correction exists to publish. ``/ground_truth/odom`` carries the
  simulator's pose in ``map`` (to see the VO's drift in RViz);
- the head camera (``camera/image_raw``, ``camera/depth``, ``camera/camera_info``, frame
  ``head_camera_optical``, its TF from base_link) when the navigator renders it anyway (``mapping``
  and ``full`` modes) or ``images="always"``;
- ``/navigate/status`` (``std_msgs/String``, transient-local): the navigator's status (``walking``,
  ``lost``, ``arrived``, ``fell``, ``stuck``, ``timeout``, ``lost_timeout``; ``no_route`` while
  its latest replan found no route, ``goal_status``) each time it changes or a goal is taken, and
  ``rejected: <why>`` for a refused goal.

The node runs in this process: rclpy's executor thread takes goals, the thread that steps the
navigator applies them and publishes (every message is built from one consistent state).
"""

from __future__ import annotations

import math
import threading
import time
from collections import Counter
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..utils.validate import Checked
from .navigator import Navigator, NavSnapshot
from .planning import ReplanRecord

TERMINAL = ("arrived", "fell", "stuck", "timeout", "lost_timeout")
"""Statuses that end an episode (the navigator stands until the next goal)."""


@dataclass(kw_only=True)
class NavigateNodeCfg(Checked):
    """Topics (relative to ``namespace`` unless they start with ``/``), frames, rates and QoS."""

    node_name: str = "ambulo_navigator"
    namespace: str = ""
    goal_topic: str = "/goal_pose"
    plan_topic: str = "plan"
    footsteps_topic: str = "footsteps"
    map_topic: str = "map"
    costmap_topic: str = "costmap"
    odom_topic: str = "odom"
    truth_topic: str = "ground_truth/odom"
    status_topic: str = "navigate/status"
    clock_topic: str = "/clock"
    camera_namespace: str = "camera"
    map_frame: str = "map"
    odom_frame: str = "odom"
    base_frame: str = "base_link"
    camera_frame: str = "head_camera_optical"
    frame_prefix: str = ""
    """Put before every frame id (``robot1/``)."""
    clock_rate_hz: float | None = None
    """/clock per second of simulated time; None: every physics step (the bridge's default; at 200 Hz
    it is half of what the node adds to the loop, ~0.4 of ~0.9 ms a step in oracle mode)."""
    map_rate_hz: float = 1.0
    """/map and /costmap per second of simulated time (the costmap is recomputed only when the map changed)."""
    images: Literal["auto", "always", "never"] = "auto"
    """``auto``: publish the camera when the navigator renders it anyway (mapping, full)."""
    use_goal_yaw: bool = True
    """Arrive facing the goal pose's heading (False: any heading)."""
    qos_depth: int = 10
    """History of the reliable topics (tests use a large one, so a starved subscriber loses nothing)."""
    fastdds_profile: bool = True
    """ambulo's Fast DDS transports (``ros2.runtime.use_fastdds_profile``)."""


class NavigateNode:
    """The node (module docstring) around ``navigator``; ``close()`` (or ``with``) leaves the graph."""

    def __init__(self, navigator: Navigator, cfg: NavigateNodeCfg | None = None):
        from ..ros2.runtime import import_rclpy, use_fastdds_profile

        self.nav, self.cfg = navigator, cfg or NavigateNodeCfg()
        self.world = navigator.world
        rclpy = import_rclpy()
        from . import ros2_messages  # after rclpy: the message packages need its libraries

        self._m = ros2_messages
        c = self.cfg
        self._odom = ros2_messages.OdometryCdr(c.frame_prefix + c.odom_frame, c.frame_prefix + c.base_frame)
        self._truth = ros2_messages.OdometryCdr(c.frame_prefix + c.map_frame, c.frame_prefix + "ground_truth")
        if self.cfg.fastdds_profile:
            use_fastdds_profile()
        self.published: Counter = Counter()
        """topic -> messages published."""
        self.goals: list[tuple[float, float, float | None]] = []
        """The goals taken (x m, y m, yaw rad or None), in order."""
        self.rejected: list[str] = []
        """Why each refused goal was refused."""
        self._lock = threading.Lock()
        self._pending: tuple[float, float, float | None] | None = None
        self._pending_rejections: list[str] = []
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(self.cfg.node_name, namespace=self.cfg.namespace or None, context=self.context)
        self._make_publishers()
        self.status: str | None = None
        """What /navigate/status said last (refusals aside)."""
        self._route = self._plan = None
        self._replans_seen = self._goal_replans = 0
        self._next_map_s = -math.inf
        self._map_key = self._costmap = None
        self._last_estimate: tuple[float, np.ndarray] | None = None
        self._dt = self.world.dt_s
        rate = self.cfg.clock_rate_hz
        self._clock_every = 1 if rate is None else max(1, round(1.0 / (rate * self._dt)))
        self._steps = 0
        navigator.add_observer(self._on_frame, images="image" in self._pubs)
        from rclpy.executors import SingleThreadedExecutor

        self._executor = SingleThreadedExecutor(context=self.context)
        self._executor.add_node(self.node)
        self._stop = threading.Event()
        self._spinner = threading.Thread(target=self._spin_executor, name="navigate-node-executor", daemon=True)
        self._spinner.start()
        self.closed = False
        self._publish_status(navigator.status)
        self._publish_maps(self.world.time_s)

    # -- set-up ---------------------------------------------------------------------------------
    def _frame(self, name: str) -> str:
        return self.cfg.frame_prefix + name

    def _make_publishers(self) -> None:
        from geometry_msgs.msg import PoseStamped
        from nav_msgs.msg import OccupancyGrid, Odometry, Path
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import CameraInfo, Image
        from std_msgs.msg import String

        from ..ros2.raw_types import clear_rcutils_error, raw_message_class

        c = self.cfg
        data = QoSProfile(depth=c.qos_depth, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        status = QoSProfile(depth=c.qos_depth, reliability=ReliabilityPolicy.RELIABLE,
                            durability=DurabilityPolicy.TRANSIENT_LOCAL)
        tf = QoSProfile(depth=max(100, c.qos_depth), reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)  # tf2_ros's broadcaster QoS
        cam = c.camera_namespace.rstrip("/")
        specs = {"clock": (Clock, c.clock_topic, data), "plan": (Path, c.plan_topic, data),
                 "footsteps": (raw_message_class("visualization_msgs/msg/MarkerArray"), c.footsteps_topic, data),
                 "map": (OccupancyGrid, c.map_topic, latched), "costmap": (OccupancyGrid, c.costmap_topic, latched),
                 "odom": (Odometry, c.odom_topic, data), "truth": (Odometry, c.truth_topic, data),
                 "tf": (raw_message_class("tf2_msgs/msg/TFMessage"), "/tf", tf),
                 "status": (String, c.status_topic, status)}
        if c.images == "always" or (c.images == "auto" and (self.nav.localizer.needs_images
                                                            or self.nav.mapper.needs_images)):
            specs.update({"image": (Image, f"{cam}/image_raw", data), "depth": (Image, f"{cam}/depth", data),
                          "info": (CameraInfo, f"{cam}/camera_info", data)})
        self._pubs = {}
        for key, (msg_type, topic, qos) in specs.items():
            pub = self.node.create_publisher(msg_type, topic, qos)
            clear_rcutils_error()
            self._pubs[key] = pub
        self.topics = {key: pub.topic_name for key, pub in self._pubs.items()}
        """key -> full topic name."""
        self.node.create_subscription(PoseStamped, c.goal_topic, self._on_goal, QoSProfile(
            depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE))

    def _spin_executor(self) -> None:
        while not self._stop.is_set() and self.context.ok():
            try:
                self._executor.spin_once(timeout_sec=0.05)
            except Exception:  # shutting down under the executor
                return

    # -- goals: taken on the executor thread, applied on the stepping thread -----------------------
    def _on_goal(self, msg) -> None:
        frame = msg.header.frame_id.removeprefix("/")
        accepted = {self._frame(self.cfg.map_frame), self._frame(self.cfg.odom_frame), ""}
        p, q = msg.pose.position, msg.pose.orientation
        values = (p.x, p.y, q.x, q.y, q.z, q.w)
        if frame not in accepted:
            why = (f"goal in frame {frame!r}: this navigator takes goals in {self._frame(self.cfg.map_frame)!r}; "
                   "set RViz's fixed frame to map")
        elif not all(math.isfinite(v) for v in values):
            why = f"goal {values} is not finite; send a pose with finite position and orientation"
        else:
            norm = math.sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w)
            yaw = self._m.yaw_of_quat_xyzw(q.x, q.y, q.z, q.w) if norm > 1e-6 else None
            with self._lock:
                self._pending = (float(p.x), float(p.y), yaw)
            return
        self.node.get_logger().warning(why)
        with self._lock:
            self._pending_rejections.append(why)

    def set_goal(self, goal_xy_m, yaw_rad: float | None = None) -> None:
        """Take a goal as if it came on the goal topic (applied at the next step)."""
        x, y = (float(v) for v in goal_xy_m)
        with self._lock:
            self._pending = (x, y, None if yaw_rad is None else float(yaw_rad))

    def _apply_goal(self) -> None:
        with self._lock:
            goal, self._pending = self._pending, None
            rejections, self._pending_rejections = self._pending_rejections, []
        for why in rejections:
            self.rejected.append(why)
            self._publish("status", _string(f"rejected: {why}"))
        if goal is None:
            return
        if self.world.fell:  # a fallen robot walks nowhere: stand it up (the navigator's reset)
            self.nav.reset()
        x, y, yaw = goal
        self.nav.set_goal((x, y), yaw if self.cfg.use_goal_yaw else None)
        self.goals.append(goal)
        self._goal_replans = len(self.nav.replans)  # the replans for this goal start here
        self._publish_status(self.nav.status)

    # -- publishing ---------------------------------------------------------------------------------
    def _publish(self, key: str, msg) -> None:
        self._pubs[key].publish(msg)
        self.published[self.topics[key]] += 1

    def _publish_status(self, status: str) -> None:
        self.status = status
        self._publish("status", _string(status))

    def _publish_maps(self, now: float) -> None:
        from ..maps import to_msg, to_occupancy_grid
        from ..ros2.messages import occupancy_grid, stamp

        nav, frame = self.nav, self._frame(self.cfg.map_frame)
        grid = nav.occupancy
        key = (id(grid), nav.mapper.version)
        if key != self._map_key:  # the costmap is worth computing only for a new map
            self._map_key, self._costmap = key, nav.costmap()
        self._publish("map", to_msg(to_occupancy_grid(grid, frame_id=frame), stamp=stamp(now)))
        self._publish("costmap", occupancy_grid(now, frame, self._costmap))
        self._next_map_s = now + 1.0 / self.cfg.map_rate_hz

    def _publish_plan(self, now: float) -> None:
        nav, frame = self.nav, self._frame(self.cfg.map_frame)
        if nav.route is not None and nav.route is not self._route:
            self._publish("plan", self._m.path_msg(now, frame, nav.route.path_xy_m))
        if nav.plan is not self._plan:
            size = nav.footsteps_stage.footstep_cfg.foot_size_m  # the sole the planner placed
            self._publish("footsteps", self._m.footstep_markers_cdr(now, frame, nav.plan, size))
        self._route, self._plan = nav.route, nav.plan

    def _on_frame(self, snap: NavSnapshot) -> None:
        """Every camera frame: odometry, TF, ground truth and (when rendered) the images."""
        m, c, now = self._m, self.cfg, snap.time_s
        est = snap.estimate.xyyaw
        velocity = (0.0, 0.0, 0.0)
        if self._last_estimate is not None and now > self._last_estimate[0]:
            t0, prev = self._last_estimate
            d = (est - prev) / (now - t0)
            cy, sy = math.cos(est[2]), math.sin(est[2])
            dyaw = math.remainder(est[2] - prev[2], math.tau) / (now - t0)
            velocity = (cy * d[0] + sy * d[1], -sy * d[0] + cy * d[1], dyaw)
        self._last_estimate = (now, est.copy())
        base, odom, map_ = self._frame(c.base_frame), self._frame(c.odom_frame), self._frame(c.map_frame)
        self._publish("odom", self._odom(now, est, velocity))
        self._publish("truth", self._truth(now, snap.true_pose))
        parents, children = [map_, odom], [odom, base]
        pos = [[0.0, 0.0, 0.0], [est[0], est[1], 0.0]]
        quat = [[0.0, 0.0, 0.0, 1.0], m.yaw_quat_xyzw(float(est[2]))]
        frame = snap.frame
        if frame is not None and "image" in self._pubs:
            base_cam = _base_to_camera(snap.true_pose, frame.pose_wc.numpy())
            parents.append(base)
            children.append(self._frame(c.camera_frame))
            pos.append(base_cam[:3, 3])
            quat.append(_quat_xyzw(base_cam[:3, :3]))
            self._publish_images(now, frame)
        self._publish("tf", m.tf_cdr(now, parents, children, np.array(pos, float), np.array(quat, float)))

    def _publish_images(self, now: float, frame) -> None:
        from ..ros2 import cdr
        from ..ros2.messages import camera_info

        ns, cam = int(round(now * 1e9)), self._frame(self.cfg.camera_frame)
        rgb = np.ascontiguousarray(frame.rgb.numpy()[..., :3], np.uint8)
        h, w = rgb.shape[:2]
        self._publish("image", cdr.image(ns, cam, h, w, "rgb8", 3 * w, rgb.tobytes()))
        depth = np.ascontiguousarray(frame.depth_m.numpy(), "<f4")  # REP 118: 32FC1, metres
        self._publish("depth", cdr.image(ns, cam, h, w, "32FC1", 4 * w, depth.tobytes()))
        self._publish("info", camera_info(now, cam, w, h, frame.intrinsics.numpy()))

    # -- the loop -----------------------------------------------------------------------------------
    def step(self) -> None:
        """One physics step of the navigator, with the goals that came in and the messages due."""
        from ..ros2 import cdr

        self._apply_goal()
        self.nav.step()
        now = self.world.time_s
        self._steps += 1
        if self._steps % self._clock_every == 0:
            self._publish("clock", cdr.clock(int(round(now * 1e9))))
        if len(self.nav.replans) != self._replans_seen:
            self._replans_seen = len(self.nav.replans)
            self._publish_plan(now)
        if now >= self._next_map_s:
            self._publish_maps(now)
        replans = self.nav.replans
        status = goal_status(self.nav.status, replans[-1] if len(replans) > self._goal_replans else None)
        if status != self.status:
            self._publish_status(status)

    def spin(self, seconds: float | None = None, *, real_time: bool = False, until=None) -> None:
        """Step for ``seconds`` of simulated time (None: until Ctrl-C or ``until(self)``); ``real_time``
        paces the steps to the wall clock (what RViz users want), else as fast as they run."""
        steps = None if seconds is None else int(round(seconds / self._dt))
        start, done = time.perf_counter(), 0
        while (steps is None or done < steps) and not (until is not None and until(self)):
            self.step()
            done += 1
            if real_time:
                ahead = done * self._dt - (time.perf_counter() - start)
                if ahead > 0:
                    time.sleep(ahead)

    # -- teardown -----------------------------------------------------------------------------------
    def close(self) -> None:
        """Leave the ROS graph (the navigator and its world stay as they are)."""
        if getattr(self, "closed", True):
            return
        self.closed = True
        self._stop.set()
        self._spinner.join(timeout=2.0)
        self._executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        self.context.try_shutdown()

    def __enter__(self) -> NavigateNode:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def goal_status(status: str, last_replan: ReplanRecord | None) -> str:
    """What /navigate/status says: the navigator's ``status``, except ``no_route`` while it walks but
    its latest replan for this goal (None: none yet) found no route to it (off the map, or walled
    in): the navigator keeps trying (the map may open up) and would only call it ``stuck`` after its
    stuck window."""
    if status == "walking" and last_replan is not None and not last_replan.route_found:
        return "no_route"
    return status


def _string(text: str):
    from std_msgs.msg import String

    return String(data=text)


def _base_to_camera(true_pose, pose_wc: np.ndarray) -> np.ndarray:
    """(4, 4) the camera in the base frame (the base on the floor, yaw only), from the true poses."""
    x, y, yaw = (float(v) for v in true_pose)
    base = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    base[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    base[:3, 3] = [x, y, 0.0]
    return np.linalg.inv(base) @ pose_wc


def _quat_xyzw(rot: np.ndarray) -> np.ndarray:
    """A rotation matrix (3, 3) as a unit quaternion x, y, z, w."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(rot).as_quat()


__all__ = ["TERMINAL", "NavigateNode", "NavigateNodeCfg", "goal_status"]
