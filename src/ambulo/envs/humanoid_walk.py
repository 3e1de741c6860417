"""humanoid-walk: the 21-DoF humanoid tracks a commanded planar velocity and yaw rate.

Observations (72, in order): projected gravity in the base frame (3), command
(vx, vy, yaw rate) scaled (3), joint positions relative to the default pose (21),
scaled joint velocities (21), scaled base angular velocity in the base frame (3), last
action (21). The critic also sees base linear velocity, base height and foot contacts.
Actions (21): joint position targets ``default + action_scale * a`` tracked by each joint's
implicit PD actuator. Falls (base below ``min_base_height_m`` or tilted past
``max_tilt_rad``) end the episode. Friction and base mass are randomized per env at start,
and every ``push_interval_s`` the bases get a random shove.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np
import torch

from ambulo import assets

from . import observations as obs_terms
from . import rewards
from .base import EnvCfg, RLEnv
from ..utils.math import quat_from_axis_angle, quat_rotate
from .registry import register
from .robot import PdRobot
from .scene import ROBOT_PREFIX, add_floor_contact_sensor, scene_spec


@dataclass(kw_only=True)
class HumanoidWalkCfg(EnvCfg):
    """humanoid-walk settings."""

    robot_file: str | None = None
    """Robot MJCF; None is the bundled ``humanoid``."""
    base_body: str = "pelvis"
    feet_bodies: tuple[str, ...] = ("left_foot", "right_foot")
    default_pose_keyframe: str | None = "home"
    """Robot-file keyframe giving the default pose and initial base height (None: qpos0)."""
    default_joint_pos: dict[str, float] = field(default_factory=dict)
    """Default pose overrides per joint name, rad."""
    action_scale: float = 0.25
    """Joint target offset for an action of 1, rad. legged_gym's 0.25: with 0.5, PPO's initial
    exploration noise toppled the stiff-jointed humanoid within 0.8 s and a 300-iteration CPU
    run reached 2.9 s episodes; with 0.25 the same run reached 17.5 s (docs/images)."""
    command_lin_vel_x: tuple[float, float] = (-1.0, 1.0)
    command_lin_vel_y: tuple[float, float] = (-0.5, 0.5)
    command_yaw_rate: tuple[float, float] = (-1.0, 1.0)
    standing_fraction: float = 0.1
    """Share of episodes commanded to stand still (zero command)."""
    min_base_height_m: float = 0.5
    max_tilt_rad: float = math.radians(60.0)
    tracking_std: float = 0.5
    """Width of the velocity tracking kernels, m/s and rad/s."""
    air_time_threshold_s: float = 0.4
    soft_joint_limit_factor: float = 0.9
    """Joint-limit penalty starts at this fraction of each joint's range about its middle."""
    friction_range: tuple[float, float] = (0.4, 1.2)
    added_base_mass_kg: tuple[float, float] = (-2.0, 3.0)
    push_interval_s: float = 8.0
    push_velocity_m_s: float = 0.5
    """Pushes add a planar base velocity uniform in +-this, m/s."""
    initial_joint_noise_rad: float = 0.05
    obs_scale_joint_vel: float = 0.05
    obs_scale_ang_vel: float = 0.25
    obs_scale_command: tuple[float, float, float] = (2.0, 2.0, 0.25)


def humanoid_walk_cfg() -> HumanoidWalkCfg:
    """Default humanoid-walk: 200 Hz physics, decimation 4 (50 Hz policy), 20 s episodes.

    Weights follow Isaac Lab's humanoid velocity tasks (tracking 1.0 / 0.5, termination
    -200, action rate -0.01, joint limits -1), per second of simulated time.
    """
    return HumanoidWalkCfg(
        physics_dt_s=0.005,
        decimation=4,
        episode_length_s=20.0,
        reward_weights=dict(
            track_lin_vel_xy_exp=1.0,
            track_ang_vel_z_exp=0.5,
            upright=0.5,
            terminated=-200.0,
            ang_vel_xy_l2=-0.05,
            torques_l2=-1.0e-5,
            action_rate_l2=-0.01,
            joint_pos_limits=-1.0,
            feet_air_time=1.0,
        ),
    )


def _keyframe_pose(robot_file: str,
                   keyframe: str | None) -> tuple[dict[str, float], torch.Tensor | None]:
    """Joint positions by name and base position (3,) of ``keyframe`` in the robot file.

    Attaching a robot to a scene drops its keyframes, so they are read from the file itself.
    """
    if keyframe is None:
        return {}, None
    model = mujoco.MjSpec.from_file(robot_file).compile()
    try:
        qpos = model.key(keyframe).qpos
    except KeyError:
        raise ValueError(f"{robot_file} has no keyframe {keyframe!r}; set "
                         "default_pose_keyframe=None to use qpos0") from None
    pose, base = {}, None
    for j in range(model.njnt):
        adr, kind = model.jnt_qposadr[j], int(model.jnt_type[j])
        if kind == mujoco.mjtJoint.mjJNT_FREE.value:
            base = torch.tensor(qpos[adr:adr + 3], dtype=torch.float64)
        elif kind in (mujoco.mjtJoint.mjJNT_HINGE.value, mujoco.mjtJoint.mjJNT_SLIDE.value):
            pose[model.joint(j).name] = float(qpos[adr])
    return pose, base


class HumanoidWalkEnv(RLEnv):
    """Velocity-tracking locomotion; see the module docstring."""

    cfg: HumanoidWalkCfg

    def __init__(self, cfg: HumanoidWalkCfg):
        robot_file = cfg.robot_file or assets.path("humanoid")
        pose, self._base_pos0 = _keyframe_pose(robot_file, cfg.default_pose_keyframe)
        pose.update(cfg.default_joint_pos)
        spec = scene_spec(robot_file)
        for foot in cfg.feet_bodies:
            add_floor_contact_sensor(spec, ROBOT_PREFIX + foot, f"{foot}_contact")
        model = spec.compile()
        self.robot = PdRobot(model, ROBOT_PREFIX + cfg.base_body, pose, ROBOT_PREFIX,
                             cfg.soft_joint_limit_factor)
        self.num_actions = self.robot.num_joints
        self._feet_sensors = np.array(
            [model.sensor(f"{foot}_contact").adr[0] for foot in cfg.feet_bodies])
        super().__init__(cfg, model)

    def _setup(self) -> None:
        n, dev, cfg = self.num_envs, self.device, self.cfg
        self.robot.to_device(dev)
        if self._base_pos0 is not None:
            self._base_pos0 = self._base_pos0.to(dev)
        self.feet_sensors = torch.as_tensor(self._feet_sensors, device=dev)
        self.commands = torch.zeros(n, 3, dtype=torch.float64, device=dev)
        """(N, 3): commanded (vx, vy) in the heading frame, m/s, and yaw rate, rad/s."""
        self.command_scale = torch.tensor(cfg.obs_scale_command, dtype=torch.float64, device=dev)
        nfeet = len(cfg.feet_bodies)
        self.feet_air_time_s = torch.zeros(n, nfeet, dtype=torch.float64, device=dev)
        self.feet_contact = torch.zeros(n, nfeet, dtype=torch.bool, device=dev)
        self.feet_first_contact = torch.zeros_like(self.feet_contact)
        self._touchdown_air_time_s = torch.zeros_like(self.feet_air_time_s)
        # set by _get_terminations each step and reused by the rewards
        self._gravity_b = torch.zeros(n, 3, dtype=torch.float64, device=dev)
        self._fell_height = torch.zeros(n, dtype=torch.bool, device=dev)
        self._fell_tilt = torch.zeros_like(self._fell_height)
        self._push_interval = max(1, round(cfg.push_interval_s / self.step_dt_s))
        self._step_count = 0
        self._randomize_physics()

    def _randomize_physics(self) -> None:
        """Per-env friction and base mass, drawn once at start (Isaac Lab's "startup" events)."""
        cfg = self.cfg
        friction = self.engine.model_field("geom_friction")
        # MuJoCo takes the larger friction of two touching geoms, so every geom gets the
        # env's sample (else the feet's own value would mask a slippery floor).
        friction[:, :, 0] = self._uniform((self.num_envs, 1), *cfg.friction_range).to(friction)
        mass = self.engine.model_field("body_mass")
        added = self._uniform((self.num_envs,), *cfg.added_base_mass_kg)
        mass[:, self.robot.base_body] += added.to(mass)
        self.engine.set_const()

    # -- state views -------------------------------------------------------------------
    @property
    def base_quat_w(self) -> torch.Tensor:
        """(N, 4) base orientation (w, x, y, z) in the world frame."""
        return self.robot.base_quat_w(self.engine)

    def velocity_tracking_error(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(N,) |v_cmd - v| of the planar base velocity, m/s, and (N,) |yaw rate error|, rad/s."""
        quat, qvel = self.base_quat_w, self.engine.qvel
        vel_yaw = obs_terms.base_lin_vel_yaw(quat, qvel[:, self.robot.lin_vel_slice])
        yaw_rate = quat_rotate(quat, qvel[:, self.robot.ang_vel_slice])[:, 2]
        lin_err = torch.linalg.vector_norm(self.commands[:, :2] - vel_yaw, dim=-1)
        return lin_err, (self.commands[:, 2] - yaw_rate).abs()

    # -- RLEnv hooks ---------------------------------------------------------------------
    def _apply_action(self, actions: torch.Tensor) -> None:
        self.robot.set_joint_targets(self.engine, actions * self.cfg.action_scale)

    def _pre_physics(self) -> None:
        self._step_count += 1
        if self._step_count % self._push_interval == 0:
            v, start = self.cfg.push_velocity_m_s, self.robot.lin_vel_slice.start
            self.engine.qvel[:, start:start + 2] += self._uniform((self.num_envs, 2), -v, v)

    def _post_physics(self) -> None:
        contact = self.engine.sensordata[:, self.feet_sensors] > 0.0
        self.feet_first_contact = (self.feet_air_time_s > 0.0) & contact
        self.feet_air_time_s += self.step_dt_s
        self._touchdown_air_time_s = self.feet_air_time_s * self.feet_first_contact
        self.feet_air_time_s *= ~contact
        self.feet_contact = contact

    def _get_observations(self) -> torch.Tensor:
        cfg, robot, engine = self.cfg, self.robot, self.engine
        qvel = engine.qvel
        return torch.cat(
            [
                obs_terms.projected_gravity_b(self.base_quat_w),
                self.commands * self.command_scale,
                robot.joint_pos_rel(engine),
                robot.joint_vel(engine) * cfg.obs_scale_joint_vel,
                qvel[:, robot.ang_vel_slice] * cfg.obs_scale_ang_vel,
                self.actions,
            ],
            dim=1,
        ).float()

    def _get_privileged_observations(self) -> torch.Tensor:
        qpos, qvel = self.engine.qpos, self.engine.qvel
        return torch.cat(
            [
                obs_terms.base_lin_vel_b(self.base_quat_w, qvel[:, self.robot.lin_vel_slice]),
                qpos[:, self.robot.pos_slice][:, 2:3],
                self.feet_contact.double(),
            ],
            dim=1,
        ).float()

    def _get_terminations(self) -> dict[str, torch.Tensor]:
        height = self.engine.qpos[:, self.robot.pos_slice.start + 2]
        self._gravity_b = obs_terms.projected_gravity_b(self.base_quat_w)
        self._fell_height = height < self.cfg.min_base_height_m
        self._fell_tilt = rewards.upright(self._gravity_b) < math.cos(self.cfg.max_tilt_rad)
        return {"base_height": self._fell_height, "tilt": self._fell_tilt}

    def _get_rewards(self) -> dict[str, torch.Tensor]:
        cfg, robot, engine = self.cfg, self.robot, self.engine
        quat, qvel = self.base_quat_w, engine.qvel
        ang_vel_b = qvel[:, robot.ang_vel_slice]
        vel_yaw = obs_terms.base_lin_vel_yaw(quat, qvel[:, robot.lin_vel_slice])
        yaw_rate_w = quat_rotate(quat, ang_vel_b)[:, 2]
        return {
            "track_lin_vel_xy_exp": rewards.track_lin_vel_xy_exp(self.commands[:, :2], vel_yaw,
                                                                 cfg.tracking_std),
            "track_ang_vel_z_exp": rewards.track_ang_vel_z_exp(self.commands[:, 2], yaw_rate_w,
                                                               cfg.tracking_std),
            "upright": rewards.upright(self._gravity_b),
            "terminated": (self._fell_height | self._fell_tilt).double(),
            "ang_vel_xy_l2": rewards.l2(ang_vel_b[:, :2]),
            "torques_l2": rewards.torques_l2(engine.actuator_force),
            "action_rate_l2": rewards.action_rate_l2(self.actions, self.prev_actions),
            "joint_pos_limits": rewards.joint_pos_limits(
                robot.joint_pos(engine), robot.soft_lower, robot.soft_upper),
            "feet_air_time": rewards.feet_air_time(
                self._touchdown_air_time_s, self.feet_first_contact, cfg.air_time_threshold_s,
                self.commands[:, :2]),
        }

    def _reset_idx(self, env_ids: torch.Tensor) -> None:
        cfg, n = self.cfg, len(env_ids)
        yaw = self._uniform((n,), -math.pi, math.pi)
        z_axis = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64, device=self.device).expand(n, 3)
        self.robot.write_base_quat(self.engine, env_ids, quat_from_axis_angle(z_axis, yaw))
        if self._base_pos0 is not None:
            self.engine.qpos[env_ids, self.robot.pos_slice] = self._base_pos0
        noise = self._uniform((n, self.robot.num_joints), -1.0, 1.0) * cfg.initial_joint_noise_rad
        self.robot.write_joint_pos(self.engine, env_ids, noise)
        cmd = torch.stack([
            self._uniform((n,), *cfg.command_lin_vel_x),
            self._uniform((n,), *cfg.command_lin_vel_y),
            self._uniform((n,), *cfg.command_yaw_rate),
        ], dim=1)
        standing = self._uniform((n, 1), 0.0, 1.0) < cfg.standing_fraction
        self.commands[env_ids] = cmd * ~standing
        self.feet_air_time_s[env_ids] = 0.0
        self.feet_contact[env_ids] = False
        self.feet_first_contact[env_ids] = False


register("humanoid-walk", HumanoidWalkEnv, humanoid_walk_cfg,
         "21-DoF humanoid tracks commanded (vx, vy, yaw rate) through joint PD targets")
