"""The humanoid's head camera on a walk around the scene's island, and RGB-D frames with
ground-truth poses rendered from it, in one of two modes (``WALK_MODES``):

- ``"policy"``: the bundled humanoid *walks* under the shipped walking policy
  (``ambulo.sim.HumanoidWalkingPolicy``) in an ``ambulo.sim.World`` holding the indoor scene,
  physics at 5 ms. A pure-pursuit path follower (``LoopFollower``) turns the loop into velocity
  commands ``(vx, 0, yaw_rate)``; the head camera renders every 1/30 s of simulated time; its
  ground-truth pose is the simulator's. So the camera carries the real gait: foot impacts,
  sway, heading wobble, the policy's tracking error (``PolicyHeadCameraWalk``).
- ``"kinematic"``: the humanoid is *played*: its root pose (and a leg swing) is written to
  ``qpos`` and MuJoCo's forward kinematics places the head site, so the camera moves as a camera
  rigidly mounted on the head would, with no controller in the loop. The motion follows human
  gait: the head rises and falls twice per stride (once per step) and sways sideways once per
  stride, a few centimetres each (Hirasaki et al. 1999, *Effects of walking velocity on vertical
  head and body movements during locomotion*, Exp. Brain Res. 127), with small yaw, roll and
  pitch oscillations of the head at the same rates (``HeadCameraWalk``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np
import torch

from ambulo.core import PhysicsCfg, Simulation
from ambulo.robots.humanoid import HEAD_CAMERA_PRIM, PELVIS_HEIGHT_M, POLICY_PHYSICS_DT_S, head_camera_cfg
from ambulo.robots.humanoid import PRIM_PATH as ROBOT_PRIM
from ambulo.scenes.indoor import IndoorScene, build_indoor_scene
from ambulo.sensors import Camera, Imu, ImuCfg
from ambulo.sensors.imu_noise import ImuNoiseCfg, euroc_adis16448
from ambulo.utils.rotations import mat_to_quat, quat_to_mat
from ambulo.utils.validate import Checked

from ..frames import RgbdFrame
from .gyro import GyroStream, mean_body_rates_rad_s


@dataclass(kw_only=True)
class WalkCfg(Checked):
    """A walk along a rounded rectangle around the origin (the scene's island), through the free
    space between the island and the furniture along the walls. ``step_hz`` to ``pitch_bob_rad``
    script the kinematic mode's head motion; in policy mode the gait makes its own."""

    speed_mps: float = 0.5
    """Walking speed along the loop (policy mode: the forward speed commanded on straights), m/s."""
    fps: float = 30.0
    """Camera frame rate, Hz (of simulated time)."""
    loop_half_m: tuple[float, float] = (2.4, 1.55)
    """Half extents of the loop's rounded rectangle along x and y, m."""
    corner_radius_m: float = 0.9
    step_hz: float = 1.8
    """Steps per second: the head bobs at this rate and sways at half of it."""
    bob_m: float = 0.025
    """Vertical head bob amplitude, m."""
    sway_m: float = 0.03
    """Lateral sway amplitude, m."""
    yaw_sway_rad: float = 0.04
    roll_sway_rad: float = 0.02
    pitch_bob_rad: float = 0.015
    camera_pitch_deg: float = 15.0
    """Head camera pitched down, deg."""
    lookahead_m: float = 0.5
    """Policy mode: the path follower steers to the loop point this far ahead of the nearest one."""
    fall_height_m: float = 0.6
    """Policy mode: a pelvis below this height counts as a fall, m."""
    imu_noise: ImuNoiseCfg = field(default_factory=euroc_adis16448)
    """Noise of the gyro that rides with the camera (``sources.gyro``; ``noiseless()`` for clean rates)."""
    imu_rate_hz: float = 200.0
    """Kinematic mode: gyro sample rate, Hz (policy mode samples every 5 ms physics step: 200 Hz)."""
    imu_seed: int = 0
    look_away: tuple[float, float, float] | None = None
    """Kinematic mode: a fast head turn (start s, duration s, angle rad): the heading gains
    ``angle * sin(pi * (t - start) / duration)`` over the duration (away and back), so the peak yaw
    rate is ``pi * angle / duration``; e.g. (3, 1, 1.57) turns 90 deg away and back at up to 280 deg/s."""


def look_away_yaw(cfg: WalkCfg, t_s: float) -> float:
    """The fast head turn's yaw offset at ``t_s`` (0 outside it), rad."""
    if cfg.look_away is None:
        return 0.0
    start, duration, angle = cfg.look_away
    if not start <= t_s <= start + duration:
        return 0.0
    return angle * math.sin(math.pi * (t_s - start) / duration)


def loop_point(cfg: WalkCfg, s_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 2) positions and (N,) headings (rad) at arc lengths ``s_m`` along the loop (wrapping),
    counter-clockwise from the middle of its bottom (y < 0) edge."""
    r = cfg.corner_radius_m
    a, b = cfg.loop_half_m[0] - r, cfg.loop_half_m[1] - r
    segments = []  # (length, start (x, y), heading at start, turn centre or None)
    for k, (start, centre) in enumerate([((-a, -b - r), (a, -b)), ((a + r, -b), (a, b)),
                                         ((a, b + r), (-a, b)), ((-a - r, b), (-a, -b))]):
        heading = k * math.pi / 2
        length = 2 * (a if k % 2 == 0 else b)
        direction = np.array([math.cos(heading), math.sin(heading)])
        segments.append((length, np.array(start, float), heading, None))
        segments.append((r * math.pi / 2, np.array(start, float) + length * direction, heading, np.array(centre)))
    total = sum(seg[0] for seg in segments)
    s = np.mod(np.asarray(s_m, float) + a, total)
    xy, yaw = np.zeros((len(s), 2)), np.zeros(len(s))
    start_s = 0.0
    for length, start, heading, centre in segments:
        sel = (s >= start_s) & (s < start_s + length)
        u = s[sel] - start_s
        if centre is None:
            xy[sel] = start + np.outer(u, [math.cos(heading), math.sin(heading)])
            yaw[sel] = heading
        else:
            ang = heading - math.pi / 2 + u / r
            xy[sel] = centre + r * np.stack([np.cos(ang), np.sin(ang)], -1)
            yaw[sel] = heading + u / r
        start_s += length
    return xy, yaw


def root_pose(cfg: WalkCfg, t_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Pelvis position (3,) m and orientation (4,) wxyz at time ``t_s`` of the walk."""
    xy, yaw = loop_point(cfg, np.array([cfg.speed_mps * t_s]))
    stride = 2 * math.pi * cfg.step_hz / 2 * t_s  # one stride = two steps
    left = np.array([-math.sin(yaw[0]), math.cos(yaw[0])])
    pos = np.array([*(xy[0] + cfg.sway_m * math.sin(stride) * left),
                    PELVIS_HEIGHT_M - 0.02 + cfg.bob_m * math.cos(2 * stride)])
    yaw_t = yaw[0] + cfg.yaw_sway_rad * math.sin(stride + 0.5) + look_away_yaw(cfg, t_s)
    roll = cfg.roll_sway_rad * math.sin(stride)
    pitch = cfg.pitch_bob_rad * math.sin(2 * stride)
    cy, sy, cr, sr, cp, sp = (math.cos(yaw_t), math.sin(yaw_t), math.cos(roll), math.sin(roll),
                              math.cos(pitch), math.sin(pitch))
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return pos, mat_to_quat(rz @ ry @ rx)


class HeadCameraWalk:
    """Renders the walk: ``frame(i)`` is RGB-D frame ``i`` (at ``i / fps`` s) with its true pose
    and the gyro readings since frame ``i - 1`` (an IMU on the pelvis, ``walk.imu_rate_hz``;
    ``pose_cam_imu`` is its extrinsic once a frame was rendered).

    ``focal_length_px`` defaults to TUM RGB-D's 525 px at 640x480, scaled with the width.
    """

    def __init__(self, scene: IndoorScene, walk: WalkCfg | None = None, *, width: int = 320, height: int = 240,
                 focal_length_px: float | None = None):
        self.scene, self.walk = scene, walk or WalkCfg()
        self.camera = head_camera(self.walk, width, height, focal_length_px)
        self.sim = Simulation(scene.spec.copy(), PhysicsCfg())  # the scene stays reusable
        self.sim.add(self.camera)
        self.engine = self.sim.start()
        self._qpos = self.engine.field("qpos")
        self._mocap = self.engine.field("mocap_pos") if scene.moving else None
        model = self.engine.model
        self._hip_pitch = [int(model.joint(f"{ROBOT_PRIM}/{side}_hip_pitch").qposadr[0])
                           for side in ("left", "right")]
        self.gyro = GyroStream(self.walk.imu_noise, self.walk.imu_seed)
        self._gyro_frame = -1
        self.pose_cam_imu: np.ndarray | None = None
        """(4, 4) the pelvis IMU's pose in the camera frame (constant: the head is rigid on the pelvis)."""

    def pose_at(self, t_s: float) -> None:
        """Put the humanoid (and the moving boxes) where they are at time ``t_s``."""
        pos, quat = root_pose(self.walk, t_s)
        q = self._qpos[0]
        q[0:3] = torch.from_numpy(pos)
        q[3:7] = torch.from_numpy(quat)
        swing = 0.3 * math.sin(math.pi * self.walk.step_hz * t_s)
        q[self._hip_pitch[0]], q[self._hip_pitch[1]] = swing, -swing
        if self._mocap is not None:
            self._mocap[0, :, :] = torch.from_numpy(self.scene.box_positions(t_s))

    def frame(self, index: int) -> RgbdFrame:
        """Render frame ``index``: RGB, metric depth, the true camera-to-world pose (OpenCV axes), gyro."""
        t_s = index / self.walk.fps
        gyro = self._gyro_until(index)
        self.pose_at(t_s)
        out = capture_frame(self.camera, t_s)
        out.gyro = gyro
        if self.pose_cam_imu is None:
            pos, quat = root_pose(self.walk, t_s)
            self.pose_cam_imu = np.linalg.inv(out.pose_wc.numpy()) @ _pose(quat_to_mat(quat), pos)
        return out

    def _gyro_until(self, index: int):
        """The gyro readings from frame ``index - 1`` to ``index`` (replayed from the start when frames
        are asked out of order, so the noise is the same whatever the order)."""
        if index != self._gyro_frame + 1:
            self.gyro.reset()
            for k in range(index):
                self._gyro_add(k)
                self.gyro.take()
        self._gyro_add(index)
        self._gyro_frame = index
        return self.gyro.take()

    def _gyro_add(self, index: int) -> None:
        fps, rate = self.walk.fps, self.walk.imu_rate_hz
        if index == 0:
            times, dt = np.zeros(1), 1.0 / rate
        else:
            n = math.ceil(rate / fps - 1e-9)
            times = np.linspace((index - 1) / fps, index / fps, n + 1)[1:]
            dt = 1.0 / (fps * n)
        rates = mean_body_rates_rad_s(lambda t: quat_to_mat(root_pose(self.walk, t)[1]), times, dt)
        self.gyro.add(times, rates, dt)

    def close(self) -> None:
        self.camera.close()


def head_camera(walk: WalkCfg, width: int, height: int, focal_length_px: float | None = None) -> Camera:
    """The RGB-D camera on the humanoid's ``head_camera_mount`` site, pitched down by
    ``walk.camera_pitch_deg``; ``focal_length_px`` defaults to TUM RGB-D's 525 px at 640x480,
    scaled with the width."""
    return Camera(head_camera_cfg(width, height, pitch_deg=walk.camera_pitch_deg, focal_length_px=focal_length_px,
                                  annotators=("rgb", "depth"), clipping_range_m=(0.1, 20.0)))


def capture_frame(camera: Camera, t_s: float) -> RgbdFrame:
    """Render ``camera`` now: RGB, metric depth and its true camera-to-world pose (OpenCV axes)."""
    out = camera.capture(0)
    t_cw = out["camera"]["extrinsics_cw"]
    return RgbdFrame(depth_m=torch.from_numpy(np.ascontiguousarray(out["depth"], np.float32)),
                     rgb=torch.from_numpy(np.ascontiguousarray(out["rgb"])),
                     intrinsics=torch.from_numpy(out["camera"]["intrinsics"]),
                     pose_wc=torch.from_numpy(np.linalg.inv(t_cw)), time_s=t_s)


WALK_MODES = ("policy", "kinematic")
"""How the humanoid moves: walking under the shipped policy, or played kinematically (module doc)."""

class LoopFollower:
    """Pure pursuit (Coulter 1992, *Implementation of the Pure Pursuit Path Tracking Algorithm*,
    CMU-RI-TR-92-01) around the walk's loop: velocity commands ``(vx, vy, yaw_rate)`` for the
    walking policy from the robot's position and heading.

    Progress along the loop is the arc length of the nearest loop point, searched in a window
    just behind and ahead of the last one (so the loop's two sides never get confused); the goal
    is the point ``lookahead_m`` further on; the yaw rate is the curvature of the arc through it,
    ``2 sin(alpha) / d``, times the forward speed (``alpha`` the goal's bearing, ``d`` its
    distance), clipped to the policy's trained range; with the goal behind, it turns at that
    range's limit and slows to a fifth of the speed."""

    def __init__(self, walk: WalkCfg, max_yaw_rate: float = 1.0):
        self.walk, self.max_yaw_rate = walk, max_yaw_rate
        self.reset()

    def reset(self) -> None:
        self.s_m = 0.0
        """Arc length of the loop point nearest the robot, m (grows past the loop's length)."""
        self.cross_track_m = 0.0
        """Distance from the robot to that point at the last command, m."""

    def command(self, xy, yaw_rad: float) -> tuple[float, float, float]:
        xy = np.asarray(xy, float)
        window = self.s_m + np.linspace(-0.2, 0.8, 101)
        points, _ = loop_point(self.walk, window)
        dist = np.linalg.norm(points - xy, axis=1)
        k = int(np.argmin(dist))
        self.s_m, self.cross_track_m = float(window[k]), float(dist[k])
        goal, _ = loop_point(self.walk, np.array([self.s_m + self.walk.lookahead_m]))
        to_goal = goal[0] - xy
        alpha = math.atan2(to_goal[1], to_goal[0]) - yaw_rad
        alpha = math.atan2(math.sin(alpha), math.cos(alpha))
        speed = self.walk.speed_mps * max(0.2, math.cos(alpha))  # slow down while facing away
        yaw_rate = 2.0 * speed * math.sin(alpha) / max(float(np.linalg.norm(to_goal)), 1e-3)
        if abs(alpha) > math.pi / 2:  # the goal is behind (the arc through it degenerates): turn round
            yaw_rate = math.copysign(self.max_yaw_rate, alpha)
        return speed, 0.0, float(np.clip(yaw_rate, -self.max_yaw_rate, self.max_yaw_rate))


class PolicyHeadCameraWalk:
    """The humanoid walking the loop under the shipped walking policy, simulated in an
    ``ambulo.sim.World`` (physics every ``POLICY_PHYSICS_DT_S``, the policy's step, from
    ``robots.humanoid``) that holds the indoor scene (built into the World's stage from
    ``scene.cfg``: the same seed, the same scene); ``frame(i)`` is the head camera's RGB-D frame
    after ``i`` frame periods of simulated time, with its simulated pose. The World's
    ``rendering_dt`` is ``1 / walk.fps``: at 30 Hz a frame period is 6 or 7 physics steps
    (20 steps every 3 frames), so frame ``i`` is at the last 5 ms step at or before ``i / 30`` s,
    and its ``time_s`` says exactly when.

    Frames come in order: asking for an earlier frame than the last resets the World and walks
    again (the simulation is deterministic, so the same frames come back). After each frame
    ``root_xy_m``, ``pelvis_height_m``, ``cross_track_m``, ``commands`` and ``clearance_m`` hold the
    walk so far, ``fell`` whether the pelvis ever dropped below ``walk.fall_height_m``.
    """

    def __init__(self, scene: IndoorScene, walk: WalkCfg | None = None, *, width: int = 320, height: int = 240,
                 focal_length_px: float | None = None, walker: bool = True):
        from ambulo.sim import HumanoidWalkingPolicy, Robot, World  # the sim layer is heavy

        self.walk = walk or WalkCfg()
        self.world = World(physics_dt=POLICY_PHYSICS_DT_S, rendering_dt=1.0 / self.walk.fps)
        self.scene = build_indoor_scene(scene.cfg, spec=self.world.stage.mjspec)
        if not self.scene.cfg.with_robot:
            raise ValueError("the policy walk needs the humanoid in the scene: IndoorSceneCfg(with_robot=True)")
        xy, yaw = loop_point(self.walk, np.zeros(1))
        self.robot = self.world.scene.add(Robot(
            prim_path=ROBOT_PRIM, name="humanoid", position=[float(xy[0, 0]), float(xy[0, 1]), 0.0],
            orientation=[math.cos(yaw[0] / 2), 0.0, 0.0, math.sin(yaw[0] / 2)]))
        self.camera = self.world.scene.add(head_camera(self.walk, width, height, focal_length_px))
        self.imu = self.world.scene.add(Imu(ImuCfg(prim_path=HEAD_CAMERA_PRIM.rsplit("/", 1)[0])))
        """Clean gyro at the camera's mount site; the walk adds ``walk.imu_noise`` (``sources.gyro``)."""
        self.gyro = GyroStream(self.walk.imu_noise, self.walk.imu_seed)
        self.pose_cam_imu: np.ndarray | None = None
        """(4, 4) the IMU's pose in the camera frame, known after the first frame."""
        self.world.reset()
        self.walker = HumanoidWalkingPolicy(self.robot)
        self.walker_enabled = walker
        """False stands the humanoid in place with its drives holding the default pose (tests use it)."""
        self.follower = LoopFollower(self.walk)
        self._decimation = int(round(self.walker.contract["control_dt_s"] / POLICY_PHYSICS_DT_S))
        self._mocap = self.world.engine.field("mocap_pos") if self.scene.moving else None
        model = self.world.engine.model
        self._robot_geoms = [g for g in range(model.ngeom) if model.geom(g).name.startswith(ROBOT_PRIM + "/")
                             or model.body(model.geom_bodyid[g]).name.startswith(ROBOT_PRIM + "/")]
        self._obstacle_geoms = [model.geom(box.name + "/geom").id for box in self.scene.solids + self.scene.moving]
        self._data = None
        self.world.add_physics_callback("perception_walk", self._on_physics_step)
        self._next = 0

    def _restart(self) -> None:
        self.world.reset()
        self.walker.initialize()
        self.follower.reset()
        self._steps = 0
        self.command = (0.0, 0.0, 0.0)
        self.root_xy_m: list[np.ndarray] = []
        self.pelvis_height_m: list[float] = []
        self.cross_track_m: list[float] = []
        self.commands: list[tuple[float, float, float]] = []
        self.clearance_m: list[float] = []
        """Per frame: the smallest distance between the humanoid's geoms and any wall, furniture or
        moving box (MuJoCo's ``mj_geomDistance``, capped at 1 m), m."""
        self.fell = False
        self._next = 0
        self.gyro.reset()

    def _sample_gyro(self) -> None:
        """The gyro now, once per simulated instant (before each physics step, and at a frame)."""
        now = self.world.current_time
        if now > self.gyro.last_time_s + 1e-9:
            rates = self.imu.clean_reading()[1][:1].cpu().numpy()
            self.gyro.add(np.array([now]), rates, POLICY_PHYSICS_DT_S)

    def _on_physics_step(self, dt_s: float) -> None:
        self._sample_gyro()
        if not self.walker_enabled:
            return
        if self._steps % self._decimation == 0:  # a new command at the policy's control rate
            pos = self.robot.entity.data.root_pos_w[0]
            self.command = self.follower.command(pos[:2].cpu().numpy(), self.walker.heading_rad)
        self.walker.forward(dt_s, self.command)
        self._steps += 1

    def _record(self) -> None:
        pos = self.robot.entity.data.root_pos_w[0].cpu().numpy()
        self.root_xy_m.append(pos[:2].copy())
        self.pelvis_height_m.append(float(pos[2]))
        self.cross_track_m.append(self.follower.cross_track_m)
        self.commands.append(self.command)
        self.fell = self.fell or pos[2] < self.walk.fall_height_m
        engine = self.world.engine
        self._data = engine.get_data(0, self._data)
        model = engine.model
        self.clearance_m.append(min(mujoco.mj_geomDistance(model, self._data, r, o, 1.0, None)
                                    for r in self._robot_geoms for o in self._obstacle_geoms))

    def frame(self, index: int) -> RgbdFrame:
        """Frame ``index`` (see the class doc): RGB, metric depth, the true camera-to-world pose."""
        if index < self._next or self._next == 0:
            self._restart()
        while self._next <= index:
            if self._next > 0:
                self.world.step(render=False)  # 1/fps s: 6 or 7 physics steps of 5 ms
            if self._mocap is not None:  # the boxes do not collide: placed where they are now
                self._mocap[0, :, :] = torch.from_numpy(self.scene.box_positions(self.world.current_time))
            self._record()
            self._sample_gyro()
            gyro = self.gyro.take()
            self._next += 1
        out = capture_frame(self.camera, self.world.current_time)
        out.gyro = gyro
        if self.pose_cam_imu is None:
            engine = self.world.engine
            site = engine.model.site(self.imu.site_name).id
            pose_wi = _pose(engine.field("site_xmat")[0, site].reshape(3, 3).cpu().numpy(),
                            engine.field("site_xpos")[0, site].cpu().numpy())
            self.pose_cam_imu = np.linalg.inv(out.pose_wc.numpy()) @ pose_wi
        return out

    def close(self) -> None:
        self.world.clear_physics_callbacks()
        self.camera.close()
        if type(self.world).instance() is self.world:
            type(self.world).clear_instance()


def _pose(rot: np.ndarray, pos: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rot, pos
    return out


def make_walk(scene: IndoorScene, walk: WalkCfg | None = None, *, mode: str, width: int = 320,
              height: int = 240, focal_length_px: float | None = None):
    """The head-camera walk of ``mode`` (``WALK_MODES``): ``PolicyHeadCameraWalk`` or ``HeadCameraWalk``."""
    if mode not in WALK_MODES:
        raise ValueError(f"unknown walk mode {mode!r}; choose one of {', '.join(WALK_MODES)}")
    cls = PolicyHeadCameraWalk if mode == "policy" else HeadCameraWalk
    return cls(scene, walk, width=width, height=height, focal_length_px=focal_length_px)


__all__ = ["HeadCameraWalk", "LoopFollower", "PolicyHeadCameraWalk",
           "WALK_MODES", "WalkCfg", "capture_frame", "head_camera", "loop_point", "make_walk", "root_pose"]
