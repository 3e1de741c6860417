"""``NavWorld``: the world a navigator runs in. A started ``core.Simulation`` of a scene with the
bundled humanoid at a start pose, its head RGB-D camera and head gyro, the ground truth (pose,
occupancy of the body band) and the monitors an episode is scored with (falls, collisions).

    world = NavWorld.from_apartment(3, start_pose=(x, y, yaw))      # a seeded apartment
    world = NavWorld.from_file("my_world.xml", start_pose=(0, 0, 0))  # a user's MJCF / USD world
    world = NavWorld.from_spec(spec, start_pose=(0, 0, 0))            # a World built in code

A user's world is the environment as given (its static geometry); the humanoid is added at the
start pose and the ground-truth occupancy is rasterized from its geoms (``ground_truth``). A
world without a plane gets the one scene builder's ground.

**Collisions** are events, not steps: every ``contact_check_every`` physics steps the contacts are
read (``engine.get_data``), and a collision is counted each time a body of the environment starts
touching a robot geom other than the soles (the two foot boxes); while it stays in touch, or
touches again within ``collision_gap_s`` (an arm brushing a wall in and out with the gait), it is
the same event. **A fall** is the pelvis below ``fall_height_m``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
import torch

from ..core import Entity, GroundCfg, PhysicsCfg, RobotCfg, Simulation, add_ground, add_robot
from ..maps import Grid2D
from ..perception.frames import RgbdFrame
from ..perception.sources.gyro import GyroStream
from ..robots import humanoid
from ..scenes.apartment import Apartment, apartment
from ..sensors import Camera, Imu, ImuCfg
from ..sensors.imu_noise import ImuNoiseCfg, euroc_adis16448
from ..utils.checks import InvalidValueError, check_vector
from ..utils.math import quat_from_yaw
from ..utils.validate import Checked
from .ground_truth import world_occupancy
from .randomization import RandomizationCfg, Randomizer


@dataclass(kw_only=True)
class NavWorldCfg(Checked):
    """The robot's sensors and the episode monitors."""

    camera_width: int = 320
    camera_height: int = 240
    camera_pitch_deg: float = humanoid.HEAD_CAMERA_PITCH_DEG
    """Head camera pitched down, deg: the floor from ~1.6 m ahead is in view."""
    focal_length_px: float | None = None
    """None: the head camera's (``humanoid.head_camera_focal_px``: 525 px at 640 px wide, scaled to
    ``camera_width``)."""
    depth_range_m: tuple[float, float] = (0.1, 20.0)
    head_lamp: float = humanoid.HEAD_LAMP_DIFFUSE
    """Diffuse intensity of the robot's head lamp (``humanoid.add_head_lamp``; 0: off)."""
    imu_noise: ImuNoiseCfg = field(default_factory=euroc_adis16448)
    """Noise of the head gyro (Kalibr model; EuRoC's ADIS16448)."""
    record_gyro: bool = True
    """Sample the gyro every physics step (the VO needs it; oracle runs may skip it)."""
    fall_height_m: float = 0.6
    """A pelvis below this height is a fall, m (standing: 0.92 m)."""
    contact_check_every: int = 4
    """Read contacts every this many physics steps (4 = the policy's 20 ms control period)."""
    collision_gap_s: float = 0.5
    """Contacts with one body less than this apart are one collision event, s."""
    map_resolution_m: float = 0.05
    """Cell side of a user world's ground-truth occupancy, m."""
    step_height_m: float = 0.03
    """Solids whose top is at or below this are walked over (the apartments' rule), m."""
    randomization: RandomizationCfg = field(default_factory=RandomizationCfg)
    """Domain randomization; ``RandomizationCfg(enabled=True)`` switches it on."""
    seed: int = 0
    """Seed of the gyro noise and of the randomization."""


def _has_plane(spec: mujoco.MjSpec) -> bool:
    return any(g.type == mujoco.mjtGeom.mjGEOM_PLANE for g in spec.geoms)


class NavWorld:
    """A started simulation of a scene with the humanoid (module docstring). Build it with
    ``from_apartment``, ``from_file`` or ``from_spec``; ``step()`` advances one physics step."""

    def __init__(self, spec: mujoco.MjSpec, start_pose, cfg: NavWorldCfg | None = None, *,
                 occupancy: Grid2D | None = None, apartment_: Apartment | None = None, cover_xy_m=None):
        self.cfg = cfg = cfg or NavWorldCfg()
        self.start_pose = tuple(float(v) for v in check_vector("start_pose", start_pose, 3, "pass (x m, y m, yaw rad)"))
        self.apartment = apartment_
        """The apartment this world was built from, or None for a user's world."""
        self.randomizer = Randomizer(cfg.randomization, cfg.seed)
        self.randomizer.edit_spec(spec, humanoid.PRIM_PATH)
        humanoid.add_head_lamp(spec, cfg.head_lamp)
        self.sim = Simulation(spec, PhysicsCfg(timestep_s=humanoid.POLICY_PHYSICS_DT_S), num_threads=1)
        self.camera = self.sim.add(Camera(humanoid.head_camera_cfg(
            cfg.camera_width, cfg.camera_height, pitch_deg=cfg.camera_pitch_deg, focal_length_px=cfg.focal_length_px,
            annotators=("rgb", "depth"), clipping_range_m=cfg.depth_range_m)))
        self.imu = self.sim.add(Imu(ImuCfg(prim_path=humanoid.HEAD_CAMERA_PRIM.rsplit("/", 1)[0])))
        """Clean gyro at the camera's mount; ``gyro`` adds ``cfg.imu_noise``."""
        self.engine = self.sim.start()
        self.model: mujoco.MjModel = self.engine.model
        self.robot = Entity(self.engine, humanoid.PRIM_PATH)
        self.dt_s = float(self.model.opt.timestep)
        self.gyro = GyroStream(cfg.imu_noise, cfg.seed)
        self._data = self.engine.get_data(0)
        model = self.model
        prefix = humanoid.PRIM_PATH + "/"
        is_robot_body = np.array([model.body(b).name.startswith(prefix) for b in range(model.nbody)])
        self._robot_geom = is_robot_body[model.geom_bodyid]
        feet = [model.body(prefix + name).id for name in humanoid.FOOT_BODIES]
        self._sole_geom = np.isin(model.geom_bodyid, feet)
        self._pelvis = model.body(prefix + humanoid.BASE_BODY).id
        cover = np.asarray([] if cover_xy_m is None else cover_xy_m, float).reshape(-1, 2)
        self.occupancy = occupancy if occupancy is not None else world_occupancy(
            model, self._data, resolution_m=cfg.map_resolution_m, step_height_m=cfg.step_height_m,
            include_xy_m=np.concatenate([[self.start_pose[:2]], cover]))
        """Ground-truth occupancy of the body band (``maps.Grid2D``); a user world's covers the start and
        ``cover_xy_m`` (``ground_truth.world_occupancy``)."""
        self._root_pos = self.robot.data.root_pos_w
        self.randomizer.initialize(self)
        self.reset_monitors()

    # -- constructors --------------------------------------------------------------------------
    @classmethod
    def from_apartment(cls, apt: Apartment | int, start_pose, cfg: NavWorldCfg | None = None) -> NavWorld:
        """A seeded apartment (``scenes.apartment``; a seed or an ``Apartment``) with its exact occupancy."""
        apt = apartment(apt) if not isinstance(apt, Apartment) else apt
        spec = apt.build(robot_pose=tuple(float(v) for v in start_pose))
        return cls(spec, start_pose, cfg, occupancy=apt.occupancy, apartment_=apt)

    @classmethod
    def from_spec(cls, spec: mujoco.MjSpec, start_pose, cfg: NavWorldCfg | None = None, *, cover_xy_m=None) -> NavWorld:
        """A user's world built in code (an ``MjSpec`` without the robot; edited in place). ``cover_xy_m``
        (K, 2): points the ground-truth map must cover besides the start (the goal), m."""
        if spec.body(humanoid.PRIM_PATH) is not None or spec.frame(humanoid.PRIM_PATH) is not None:
            raise InvalidValueError("spec", humanoid.PRIM_PATH, "the world already holds a robot at the humanoid's prim path",
                                    "pass the environment alone: the navigator adds the humanoid at the start pose")
        x, y, yaw = check_vector("start_pose", start_pose, 3, "pass (x m, y m, yaw rad)")
        if not _has_plane(spec):
            add_ground(spec, GroundCfg())
        add_robot(spec, RobotCfg(file=humanoid.ASSET, prim_path=humanoid.PRIM_PATH, pos_m=(x, y, 0.0),
                                 quat=quat_from_yaw(yaw).tolist()))
        return cls(spec, start_pose, cfg, cover_xy_m=cover_xy_m)

    @classmethod
    def from_file(cls, path: str | Path, start_pose, cfg: NavWorldCfg | None = None, *, cover_xy_m=None) -> NavWorld:
        """A user's MJCF (``.xml``) or USD (``.usd``, ``.usda``, ``.usdc``) world file (``cover_xy_m``: as
        ``from_spec``)."""
        file = Path(path).expanduser()
        if not file.is_file():
            raise InvalidValueError("world file", str(path), "no such file", "pass the path of an MJCF or USD world")
        if file.suffix.lower() not in (".xml", ".mjcf", ".usd", ".usda", ".usdc", ".usdz"):
            raise InvalidValueError("world file", str(path), f"unknown format {file.suffix!r}",
                                    "pass an MJCF (.xml) or USD (.usd/.usda/.usdc) world")
        return cls.from_spec(mujoco.MjSpec.from_file(str(file)), start_pose, cfg, cover_xy_m=cover_xy_m)

    # -- state --------------------------------------------------------------------------------
    @property
    def time_s(self) -> float:
        """Simulated time since the start, s."""
        return float(self.engine.field("time")[0])

    def true_pose(self) -> np.ndarray:
        """(3,) float64 ground-truth base pose (x m, y m, yaw rad) of the pelvis, world frame."""
        q = self.robot.data.root_quat_w[0]
        w, x, y, z = (float(v) for v in q)
        p = self._root_pos[0]
        return np.array([float(p[0]), float(p[1]), math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))])

    @property
    def pelvis_height_m(self) -> float:
        return float(self._root_pos[0, 2])

    def base_speed_m_s(self) -> float:
        """Horizontal speed of the pelvis, m/s."""
        v = self.robot.data.root_lin_vel_w[0]
        return float(math.hypot(float(v[0]), float(v[1])))

    def reset_monitors(self) -> None:
        self.fell = False
        """Whether the pelvis ever dropped below ``cfg.fall_height_m``."""
        self.collisions: list[tuple[float, str]] = []
        """One (time s, name of the environment's body) per collision event (module docstring)."""
        self.collision_parts: list[str] = []
        """Per collision event, the robot's bodies in that contact (names joined by "+"): which part
        touched (a forearm swung in a turn, a shin walking into clutter) tells the causes apart."""
        self._last_touch_s: dict[int, float] = {}
        self._steps = 0
        self.gyro.reset()

    # -- stepping -----------------------------------------------------------------------------
    def step(self) -> None:
        """One physics step, then the monitors (gyro every step, contacts every few)."""
        if self.cfg.record_gyro:
            self._sample_gyro()
        self.randomizer.before_step(self)
        self.sim.step()
        self._steps += 1
        if self._root_pos[0, 2] < self.cfg.fall_height_m:
            self.fell = True
        if self._steps % self.cfg.contact_check_every == 0:
            self._check_contacts()

    def _sample_gyro(self) -> None:
        now = self.time_s
        if now > self.gyro.last_time_s + 1e-9:
            rates = self.imu.clean_reading()[1][:1].numpy()
            self.gyro.add(np.array([now]), rates, self.dt_s)

    def _check_contacts(self) -> None:
        data = self._data = self.engine.get_data(0, self._data)
        touching: set[int] = set()
        if data.ncon:
            geom = np.asarray(data.contact.geom)[:data.ncon]
            robot = self._robot_geom[geom]
            mixed = robot[:, 0] != robot[:, 1]
            if mixed.any():
                g = geom[mixed]
                rob = np.where(robot[mixed][:, 0], g[:, 0], g[:, 1])
                other = np.where(robot[mixed][:, 0], g[:, 1], g[:, 0])
                hits = ~self._sole_geom[rob]
                parts: dict[int, set[int]] = {}
                for env_body, robot_body in zip(self.model.geom_bodyid[other[hits]], self.model.geom_bodyid[rob[hits]]):
                    parts.setdefault(int(env_body), set()).add(int(robot_body))
                touching = set(parts)
        now = self.time_s
        for body in touching:
            if now - self._last_touch_s.get(body, -np.inf) > self.cfg.collision_gap_s:
                self.collisions.append((now, self.model.body(body).name or f"body {body}"))
                self.collision_parts.append("+".join(sorted(self.model.body(b).name or f"body {b}"
                                                            for b in parts[body])))
            self._last_touch_s[body] = now

    # -- sensors ------------------------------------------------------------------------------
    def capture(self) -> RgbdFrame:
        """The head camera now: RGB (H, W, 3) uint8, metric depth (H, W) float32, the true
        camera-to-world pose (OpenCV axes), and the gyro readings since the last capture
        (``frame.gyro``; None on the first). Sensor noise from the randomization is added."""
        out = self.camera.capture(0)
        depth = np.ascontiguousarray(out["depth"], np.float32)
        rgb = np.ascontiguousarray(out["rgb"])
        rgb, depth = self.randomizer.noisy_images(rgb, depth)
        frame = RgbdFrame(depth_m=torch.from_numpy(depth), rgb=torch.from_numpy(rgb),
                          intrinsics=torch.from_numpy(out["camera"]["intrinsics"]),
                          pose_wc=torch.from_numpy(np.linalg.inv(out["camera"]["extrinsics_cw"])), time_s=self.time_s)
        if self.cfg.record_gyro:
            self._sample_gyro()
            frame.gyro = self.gyro.take()
        return frame

    def camera_pose_wc(self) -> np.ndarray:
        """(4, 4) true camera-to-world pose now (OpenCV axes)."""
        return np.linalg.inv(self.camera.get_extrinsics_matrix()[0])

    def pose_cam_imu(self) -> np.ndarray:
        """(4, 4) the gyro's site in the camera frame (constant: both ride the head)."""
        site = self.model.site(self.imu.site_name).id
        data = self._data = self.engine.get_data(0, self._data)
        pose_wi = np.eye(4)
        pose_wi[:3, :3], pose_wi[:3, 3] = data.site_xmat[site].reshape(3, 3), data.site_xpos[site]
        return np.linalg.inv(self.camera_pose_wc()) @ pose_wi

    def base_in_camera(self) -> np.ndarray:
        """(4, 4) the pelvis frame (yaw only, at floor height) in the camera frame now: how a
        camera pose estimate becomes a base pose estimate (the head moves little on the pelvis)."""
        x, y, yaw = self.true_pose()
        base = np.eye(4)
        c, s = math.cos(yaw), math.sin(yaw)
        base[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
        base[:3, 3] = [x, y, 0.0]
        return np.linalg.inv(self.camera_pose_wc()) @ base

    def textured_geoms(self) -> tuple[int, int]:
        """(textured, all) visible geoms of the world around the robot: full mode's visual odometry
        tracks image features, which plain-coloured surfaces do not have (a user's MJCF room of
        rgba-only boxes loses its pose; the same room with textures arrives)."""
        model = self.model
        visible = ~self._robot_geom & (model.geom_rgba[:, 3] > 0)
        matid = model.geom_matid
        has_texture = np.zeros(model.ngeom, bool)
        if model.nmat:
            mat_textured = (model.mat_texid >= 0).any(axis=1)
            has_texture[matid >= 0] = mat_textured[matid[matid >= 0]]
        return int((visible & has_texture).sum()), int(visible.sum())

    def close(self) -> None:
        self.camera.close()


__all__ = ["NavWorld", "NavWorldCfg"]
