"""The worlds ``ambulo bridge`` serves: the bundled Jetbot or humanoid on a ground plane, or a file.

Each gets an IMU on its base and a camera where the robot has one (the Jetbot's ``camera_mount``,
the humanoid's ``head_camera_mount``), so every topic of the bridge has a source. The humanoid's
World steps the physics_dt its walking policy was trained at (``robots.humanoid.POLICY_PHYSICS_DT_S``,
from the policy's contract; the bridge drives /cmd_vel through it); the others step 0.01 s.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..robots import humanoid
from ..utils.validate import Checked


@dataclass(kw_only=True)
class SceneCfg(Checked):
    physics_dt_s: float | None = None
    """s per physics step: joint states, /tf, /odom, /clock and the IMU publish at 1 / physics_dt_s.
    None: the scene's own (the humanoid its walking policy's, ``robots.humanoid.POLICY_PHYSICS_DT_S``;
    the others 0.01)."""
    camera: bool = True
    camera_width: int = 320
    camera_height: int = 240
    lidar: bool = False


def _world(cfg: SceneCfg, default_dt_s: float = 0.01):
    from ..sim import World

    world = World(physics_dt=default_dt_s if cfg.physics_dt_s is None else cfg.physics_dt_s)
    world.scene.add_default_ground_plane()
    return world


def _sensors(world, imu_path: str, camera_path: str | None, lidar_path: str | None, cfg: SceneCfg) -> None:
    from ..sensors import Camera, CameraCfg, Imu, ImuCfg, Lidar, lidar_2d

    world.scene.add(Imu(ImuCfg(prim_path=imu_path)))
    if cfg.camera and camera_path is not None:
        world.scene.add(Camera(CameraCfg(prim_path=camera_path, width=cfg.camera_width, height=cfg.camera_height,
                                         annotators=("rgb", "depth"))))
    if cfg.lidar and lidar_path is not None:
        world.scene.add(Lidar(lidar_2d(lidar_path)))


def jetbot_world(cfg: SceneCfg | None = None):
    """The Jetbot at the origin facing +x: a ``WheeledRobot`` that /cmd_vel drives."""
    from .. import assets
    from ..sim import WheeledRobot

    cfg = cfg or SceneCfg()
    world = _world(cfg)
    world.scene.add(WheeledRobot(prim_path="/World/Jetbot", name="jetbot", create_robot=True,
                                 usd_path=assets.path("jetbot"), wheel_dof_names=["left_wheel_joint", "right_wheel_joint"]))
    _sensors(world, "/World/Jetbot/chassis/imu", "/World/Jetbot/camera_mount/camera",
             "/World/Jetbot/chassis/lidar", cfg)
    world.reset()
    return world


def humanoid_world(cfg: SceneCfg | None = None):
    """The 21-DoF humanoid on a ground plane, stepping ``robots.humanoid.POLICY_PHYSICS_DT_S`` (the
    physics_dt its shipped walking policy was trained at, from the policy's contract) unless ``cfg`` says
    otherwise; a bridge drives its /cmd_vel through the walking policy, its joints from the joint
    command topics."""
    from .. import assets
    from ..sim import Robot, add_reference_to_stage

    cfg = cfg or SceneCfg()
    prim = humanoid.STAGE_PRIM_PATH
    world = _world(cfg, humanoid.POLICY_PHYSICS_DT_S)
    add_reference_to_stage(usd_path=assets.path(humanoid.ASSET), prim_path=prim)
    world.scene.add(Robot(prim_path=prim, name="humanoid"))
    _sensors(world, f"{prim}/{humanoid.IMU_SITE}", humanoid.head_camera_prim(prim), None, cfg)
    world.reset()
    return world


def file_world(path: str, cfg: SceneCfg | None = None):
    """Any robot file ambulo loads (MJCF, URDF, USD) as ``/World/Robot`` on a ground plane."""
    from ..sim import Robot, add_reference_to_stage

    cfg = cfg or SceneCfg()
    world = _world(cfg)
    add_reference_to_stage(usd_path=path, prim_path="/World/Robot")
    world.scene.add(Robot(prim_path="/World/Robot", name="robot"))
    world.reset()
    return world


SCENES = {"jetbot": jetbot_world, "humanoid": humanoid_world}
"""Bundled scenes ``ambulo bridge <name>`` serves."""

__all__ = ["SCENES", "SceneCfg", "file_world", "humanoid_world", "jetbot_world"]
