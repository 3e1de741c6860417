"""``SceneDiscovery``: what a ``Ros2Bridge`` finds in its World, found once when it attaches.

The robots (articulations) and their frames, the robot that takes commands and the joints it accepts,
the IMUs, cameras and lidars, and the fixed frames of those sensors in their mount bodies. Nothing
here changes after discovery; the publisher process's spec and the physics-thread publisher read it.
"""

from __future__ import annotations

from .commands import names_problem
from .frames import OPTICAL_FROM_GL, leaf, robot_frames, static_from_world


class SceneDiscovery:
    """The bridge's view of ``world`` under ``cfg`` (a ``BridgeCfg``).

    Attributes: ``robots`` (``frames.RobotFrames`` of every articulation), ``robot`` (the one that
    takes commands, or None), ``joint_names`` (every robot's, prefixed by its name when there are
    several), ``command_joints``, ``imus``, ``cameras``, ``lidars``, ``links`` (the dynamic frames of
    /tf), ``base_frame``, ``sensor_frames`` (the sensors' fixed frames) and ``sensor_frame``
    (``id(sensor)`` -> its frame name).
    """

    def __init__(self, world, cfg):
        from ..sensors import Camera, Imu, Lidar
        from ..sim import Articulation

        self.world, self.cfg = world, cfg
        model = world.model
        robots = [p for p in world.scene.prims() if isinstance(p, Articulation)]
        several = len(robots) > 1
        self.robots = [robot_frames(model, r, r.name, cfg.frame_prefix + (f"{r.name}/" if several else ""),
                                    cfg.frame_prefix + cfg.odom_frame, cfg.base_frame) for r in robots]
        names = [r.name for r in robots]
        if cfg.robot is not None and cfg.robot not in names:
            raise ValueError(f"BridgeCfg.robot={cfg.robot!r} is not a robot of the scene; robots: {names}")
        self.robot = next((r for r in robots if cfg.robot in (None, r.name)), None)
        self.joint_names = [(f"{r.name}/" if several else "") + j for r in robots for j in r.entity.joint_names]
        self.command_joints: list[str] = []
        if self.robot is not None:
            known = list(self.robot.entity.joint_names)
            self.command_joints = list(cfg.command_joints) if cfg.command_joints is not None else known
            problem = names_problem(self.command_joints, known)
            if problem:
                raise ValueError(f"BridgeCfg.command_joints: {problem}")
        sensors = [getattr(c, "sensor", c) for c in world.sim.components.values()]
        self.imus = [s for s in sensors if isinstance(s, Imu)]
        self.cameras = [s for s in sensors if isinstance(s, Camera)]
        self.lidars = [s for s in sensors if isinstance(s, Lidar)]
        self.links = [link for r in self.robots for link in r.dynamic]
        self.base_frame = next((r.dynamic[0].child for r in self.robots if r.robot is self.robot), "")
        self.sensor_frame: dict[int, str] = {}
        self.sensor_frames = self._sensor_frames()

    def frame_of_body(self, body: int) -> str:
        """The frame of body ``body``: its robot link's, else the fixed frame (odom)."""
        for robot in self.robots:
            if body in robot.frame_of_body:
                return robot.frame_of_body[body]
        return self.cfg.frame_prefix + self.cfg.odom_frame

    def _sensor_frames(self) -> list:
        """Fixed frames of the IMUs, cameras (optical) and lidars in their mount bodies."""
        engine, model, prefix = self.world.engine, self.world.model, self.cfg.frame_prefix
        xpos, xmat = engine.field("xpos")[0].cpu().numpy(), engine.field("xmat")[0].cpu().numpy().reshape(-1, 3, 3)
        frames = []
        for imu in self.imus:
            site = model.site(imu.site_name).id
            body = int(model.site_bodyid[site])
            pos = engine.field("site_xpos")[0, site].cpu().numpy()
            rot = engine.field("site_xmat")[0, site].cpu().numpy().reshape(3, 3)
            frames.append(static_from_world(self.frame_of_body(body), prefix + leaf(imu.prim_path),
                                            xpos[body], xmat[body], pos, rot))
        for camera in self.cameras:
            body = camera._mount_pose.body_id
            pos, rot_gl = (a[0] for a in camera._pose_gl())
            frames.append(static_from_world(self.frame_of_body(body), prefix + leaf(camera.prim_path) + "_optical",
                                            xpos[body], xmat[body], pos, rot_gl @ OPTICAL_FROM_GL))
        for lidar in self.lidars:
            body = lidar._mount_pose.body_id
            mount_pos, mount_rot = (t[0].cpu().numpy() for t in (lidar._mount_pose.pos_w(), lidar._mount_pose.rot_w()))
            pos = mount_pos + mount_rot @ lidar._offset_m.cpu().numpy()
            rot = mount_rot @ lidar._rot_ms.cpu().numpy()
            frames.append(static_from_world(self.frame_of_body(body), prefix + leaf(lidar.prim_path),
                                            xpos[body], xmat[body], pos, rot))
        for sensor, frame in zip(self.imus + self.cameras + self.lidars, frames):
            self.sensor_frame[id(sensor)] = frame.child
        return frames


__all__ = ["SceneDiscovery"]
