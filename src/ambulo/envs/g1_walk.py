"""g1-walk: Unitree G1 (29 DoF, the URDF of ``example-robot-data``) tracks a planar velocity.

The same task as humanoid-walk (observations, rewards, commands, falls, evaluation and the
``walks`` criterion), on a real robot's published model. Needs the ``robots`` extra.

Drive gains come from the URDF, joint by joint (``g1_drive_gains``):
  * stiffness ``kp = effort / q_sat``: the joint reaches its effort limit (URDF ``<limit
    effort>``) ``q_sat`` = 0.5 rad from its target, so actions (0.25 rad per unit) stay
    inside the motor's torque range and saturate only under large errors;
  * damping ``kd = min(2 zeta sqrt(kp I), effort / velocity)`` with I the joint's reflected
    link inertia at the default pose (the diagonal of MuJoCo's joint-space inertia matrix,
    the limb it swings) and zeta = 0.7: near-critical damping of that limb, capped so the
    damping torque at the joint's velocity limit (URDF ``<limit velocity>``) is no more than
    its effort limit, as a motor's torque-speed line is.
Joints get the motors' reflected rotor inertia as armature (``rotor_armature``).
Only the feet's contact spheres touch the ground (every other link has contype 0): the fall
termination ends an episode before the pelvis is low enough for knees or hands to reach it,
and MuJoCo Warp then checks 8 sphere-plane pairs per world instead of ~30 mesh-plane ones.
"""

from __future__ import annotations

import dataclasses
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import torch

from ambulo.core import RobotCfg
from ambulo.core.importers.packages import package_search_path

from .humanoid_walk import (
    WALKS,
    HumanoidWalkCfg,
    HumanoidWalkEnv,
    as_play,
    humanoid_walk_cfg,
    humanoid_walk_metrics,
    humanoid_walk_ppo,
)
from .registry import TaskSpec, register

G1_URDF = "example-robot-data/robots/g1_description/urdf/g1_29dof_rev_1_0.urdf"

# knees bent, arms slightly out: the pose of Unitree's G1 deployment examples and mjlab's
# "knees_bent" keyframe (pelvis 0.76 m above the ground)
G1_DEFAULT_POSE = {
    ".*_hip_pitch_joint": -0.312, ".*_knee_joint": 0.669, ".*_ankle_pitch_joint": -0.363,
    ".*_elbow_joint": 0.6, "left_shoulder_roll_joint": 0.2, "right_shoulder_roll_joint": -0.2,
    ".*_shoulder_pitch_joint": 0.2,
}


def g1_urdf_path() -> Path:
    """The G1 URDF of the ``example-robot-data`` pip package; FileNotFoundError with the fix."""
    for share in package_search_path():
        path = share / G1_URDF
        if path.is_file():
            return path
    raise FileNotFoundError("g1-walk needs the Unitree G1 URDF of example-robot-data; "
                            "pip install 'ambulo[robots]'")


def urdf_joint_limits(path: Path) -> dict[str, tuple[float, float]]:
    """joint name -> (effort N m, velocity rad/s) from the URDF's ``<limit>`` tags."""
    out = {}
    for joint in ET.parse(path).getroot().iter("joint"):
        limit = joint.find("limit")
        if limit is not None and limit.get("effort") and limit.get("velocity"):
            out[joint.get("name")] = (float(limit.get("effort")), float(limit.get("velocity")))
    return out


def rotor_armature(effort_n_m: float) -> float:
    """Reflected rotor inertia (kg m^2) of a G1 joint motor, by its effort class.

    The URDF has link inertias but no rotor inertia; without it a foot (3e-4 kg m^2 about the
    ankle) under a 70 N m/rad drive rings at 470 rad/s, too fast for the 5 ms step. The
    values are the G1 actuators' rotor inertia times gear ratio squared as published in
    mjlab's G1 constants (large 7520 hip/knee motors 0.025, 5020 ankle/waist pairs ~0.0072,
    arm motors ~0.0036-0.004), rounded to the effort classes of the URDF."""
    if effort_n_m >= 88.0:
        return 0.025
    if effort_n_m >= 35.0:
        return 0.0072
    return 0.004


def g1_drive_gains(model: mujoco.MjModel, qpos: np.ndarray, joint_names: list[str], qvel_adr: list[int],
                   limits: dict[str, tuple[float, float]], q_sat_rad: float = 0.5,
                   zeta: float = 0.7) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(kp, kd, I) per joint as the module docstring derives them; ``qpos`` the default pose."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    inertia = np.array([full[a, a] for a in qvel_adr])
    effort = np.array([limits[name][0] for name in joint_names])
    velocity = np.array([limits[name][1] for name in joint_names])
    kp = effort / q_sat_rad
    kd = np.minimum(2.0 * zeta * np.sqrt(kp * inertia), effort / velocity)
    return kp, kd, inertia


@dataclass(kw_only=True)
class G1WalkCfg(HumanoidWalkCfg):
    """g1-walk settings: humanoid-walk's, on the G1."""

    q_sat_rad: float = 0.5
    """Offset from target at which a joint reaches its effort limit (sets kp)."""
    damping_ratio: float = 0.7
    feet_only_ground_contact: bool = True


def g1_walk_cfg() -> G1WalkCfg:
    """humanoid-walk's settings (rewards, commands, physics, noise) on the G1."""
    shared = humanoid_walk_cfg()
    cfg = G1WalkCfg(**{f.name: getattr(shared, f.name) for f in dataclasses.fields(HumanoidWalkCfg)})
    cfg.robot = RobotCfg(file=str(g1_urdf_path()), prim_path="/World/robot", pos_m=(0.0, 0.0, 0.76))
    cfg.robot_keyframe = None
    cfg.default_joint_pos = {name: value for name in urdf_joint_limits(Path(cfg.robot.file))
                             for pattern, value in G1_DEFAULT_POSE.items() if re.fullmatch(pattern, name)}
    cfg.feet_bodies = ("left_ankle_roll_link", "right_ankle_roll_link")
    cfg.min_base_height_m = 0.45
    cfg.deviation_joints = (".*_hip_yaw_joint", ".*_hip_roll_joint", "waist_.*", ".*_shoulder_.*",
                            ".*_elbow_joint", ".*_wrist_.*")
    cfg.added_base_mass_kg = (-1.0, 3.0)
    return cfg


def g1_walk_play_cfg() -> G1WalkCfg:
    return as_play(g1_walk_cfg())


class G1WalkEnv(HumanoidWalkEnv):
    """humanoid-walk on the G1 with URDF-derived drive gains."""

    cfg: G1WalkCfg

    def _design_scene(self, spec) -> None:
        super()._design_scene(spec)
        self._g1_spec(spec)

    def _g1_spec(self, spec) -> None:
        """The G1's edits of the compiled scene: rotor armature, and only the feet touch the ground
        (g1-rough calls it after building its terrain ground)."""
        prefix = self.cfg.robot.prim_path + "/"
        limits = urdf_joint_limits(Path(self.cfg.robot.file))
        for joint in spec.joints:
            name = joint.name.removeprefix(prefix)
            if name in limits:
                joint.armature = rotor_armature(limits[name][0])
        if not self.cfg.feet_only_ground_contact:
            return
        feet = tuple(prefix + b for b in self.cfg.feet_bodies)
        for geom in spec.geoms:
            body = geom.parent.name if geom.parent is not None else ""
            if body.startswith(prefix) and body not in feet:
                geom.contype, geom.conaffinity = 0, 0

    def _setup(self) -> None:
        super()._setup()
        robot, model = self.robot, self.engine.model
        names = [f"{self.cfg.robot.prim_path}/{n}" for n in robot.joint_names]
        qvel_adr = [int(model.joint(n).dofadr[0]) for n in names]
        qpos = model.qpos0.copy()
        for name, value in zip(names, robot.default_joint_pos.reshape(-1, robot.num_joints)[0].tolist()):
            qpos[model.joint(name).qposadr[0]] = value
        kp, kd, inertia = g1_drive_gains(model, qpos, robot.joint_names, qvel_adr,
                                         urdf_joint_limits(Path(self.cfg.robot.file)),
                                         self.cfg.q_sat_rad, self.cfg.damping_ratio)
        self.drive_gains = {"kp": kp, "kd": kd, "inertia": inertia}
        dt = self.engine.dtype
        robot.write_gains(kp=torch.as_tensor(kp, dtype=dt, device=self.device).expand(self.num_envs, -1),
                          kd=torch.as_tensor(kd, dtype=dt, device=self.device).expand(self.num_envs, -1))


register(TaskSpec(
    name="g1-walk",
    env_cls=G1WalkEnv,
    cfg_fn=g1_walk_cfg,
    play_cfg_fn=g1_walk_play_cfg,
    ppo_cfg_fn=humanoid_walk_ppo,
    description="Unitree G1 (29 DoF URDF, robots extra) tracks (vx, vy, yaw rate); URDF-derived gains",
    step_metrics=humanoid_walk_metrics,
    criteria=(WALKS,),
))

__all__ = ["G1WalkCfg", "G1WalkEnv", "g1_drive_gains", "g1_urdf_path", "g1_walk_cfg", "urdf_joint_limits"]
