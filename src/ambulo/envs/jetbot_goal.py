"""jetbot-goal: drive the two-wheeled Jetbot to a random goal on the floor.

Observations (9): goal position in the base frame (x, y) m, goal distance m, base forward
velocity m/s, yaw rate rad/s, wheel speeds scaled (2), last action (2). Actions (2):
left/right wheel speed targets in units of ``max_wheel_speed_rad_s``, tracked by the
wheels' velocity actuators. Reaching the goal ends the episode as a success.

jetbot-goal-vision: the same task seen through the robot's camera (a ``TiledCamera``, so MuJoCo
Warp: ``engine="warp"``, on CUDA or Warp's CPU device). The policy gets the 64 x 64 rgb image
average-pooled to 16 x 16 x 3 in place of the goal position and distance, which only the critic
sees; the goal is a red post the camera can see (jetbot-goal's 2 mm disc is under a pixel tall
at 1.5 m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import torch
import torch.nn.functional as F

from ambulo.core import GroundCfg, PhysicsCfg, RobotCfg
from ambulo.core.rows import fill_rows, put_rows, take_rows
from ambulo.sensors import TiledCamera, TiledCameraCfg
from ambulo.utils.validate import rule

from ..utils.math import quat_from_yaw
from . import observations as obs_terms
from . import rewards
from .base import EnvCfg, RLEnv
from .ppo import PpoCfg
from .registry import Criterion, TaskSpec, register


@dataclass(kw_only=True)
class JetbotGoalCfg(EnvCfg):
    """jetbot-goal settings."""

    max_wheel_speed_rad_s: float = 20.0
    """Wheel speed for an action of 1: 20 rad/s x 0.03 m radius = 0.6 m/s."""
    goal_distance_m: tuple[float, float] = field(default=(0.5, 1.5), metadata=rule(pair=True))
    goal_radius_m: float = 0.1
    """The goal counts as reached within this distance of the chassis origin, m."""
    obs_scale_wheel_vel: float = 0.05


def jetbot_goal_cfg() -> JetbotGoalCfg:
    """Default jetbot-goal: 200 Hz physics, 20 Hz policy, 10 s episodes."""
    return JetbotGoalCfg(
        robot=RobotCfg(file="jetbot", prim_path="/World/jetbot"),
        ground=GroundCfg(static_friction=1.0, dynamic_friction=1.0, restitution=0.0),
        physics=PhysicsCfg(timestep_s=0.005, integrator="implicitfast", solver_iterations=50),
        decimation=10,
        episode_length_s=10.0,
        action_clip=1.0,
        reward_weights=dict(progress=2.0, goal_reached=200.0, action_rate_l2=-0.01),
    )


def jetbot_goal_ppo() -> PpoCfg:
    return PpoCfg(num_envs=256, max_iterations=300, num_steps_per_env=32, save_interval=50,
                  actor_hidden_dims=(64, 64), critic_hidden_dims=(64, 64))


class JetbotGoalEnv(RLEnv):
    """Goal reaching with a differential drive; see the module docstring."""

    cfg: JetbotGoalCfg

    def _design_scene(self, spec) -> None:
        goal = spec.worldbody.add_body(name="/World/goal", mocap=True, pos=[1.0, 0.0, 0.0])
        goal.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[self.cfg.goal_radius_m, 0.002, 0],
                      rgba=[0.9, 0.2, 0.2, 0.6], contype=0, conaffinity=0)

    def _setup(self) -> None:
        n, dev = self.num_envs, self.device
        self.goal_pos_w = torch.zeros(n, 3, dtype=torch.float32, device=dev)
        """(N, 3) goal position in the world frame, m."""
        self._distance = torch.zeros(n, dtype=torch.float32, device=dev)
        self._progress = torch.zeros_like(self._distance)
        self._reached = torch.zeros(n, dtype=torch.bool, device=dev)
        self._zeros = torch.zeros(n, self.robot.num_joints, dtype=self.engine.dtype, device=dev)

    def _goal_distance(self) -> torch.Tensor:
        base_xy = self.robot.data.root_pos_w[:, :2].float()
        return torch.linalg.vector_norm(self.goal_pos_w[:, :2] - base_xy, dim=-1)

    def _apply_action(self, actions: torch.Tensor) -> None:
        # velocity drives (kp = 0): tau = kd (w_target - w)
        self.robot.set_joint_targets(self._zeros, vel=actions * self.cfg.max_wheel_speed_rad_s)

    def _post_physics(self) -> None:
        distance = self._goal_distance()
        self._progress = (self._distance - distance) / self.step_dt_s
        self._distance = distance

    def _policy_terms(self) -> dict[str, torch.Tensor]:
        data = self.robot.data
        goal_b = obs_terms.goal_pos_b(data.root_pos_w, data.root_quat_w, self.goal_pos_w.to(self.engine.dtype))
        return {
            "goal_pos_b": goal_b[:, :2],
            "goal_distance": self._distance.unsqueeze(1),
            "forward_vel": data.root_lin_vel_b[:, :1],
            "yaw_rate": data.root_ang_vel_b[:, 2:3],
            "wheel_vel": data.joint_vel * self.cfg.obs_scale_wheel_vel,
            "actions": self.actions,
        }

    def _get_terminations(self) -> dict[str, torch.Tensor]:
        self._reached = self._distance < self.cfg.goal_radius_m
        return {"goal_reached": self._reached,
                "flipped": rewards.upright(self.robot.data.projected_gravity_b) < 0.5}

    def _get_rewards(self) -> dict[str, torch.Tensor]:
        return {
            "progress": self._progress,
            "goal_reached": self._reached.float(),
            "action_rate_l2": rewards.action_rate_l2(self.actions, self.prev_actions),
        }

    def _reset_idx(self, rows: torch.Tensor) -> None:
        n, cfg = self._num_rows(rows), self.cfg
        yaw = self._uniform((n,), -math.pi, math.pi, dtype=self.engine.dtype)
        self.robot.write_root_pose(quat_w=quat_from_yaw(yaw), env_ids=rows)
        bearing = self._uniform((n,), -math.pi, math.pi)
        distance = self._uniform((n,), *cfg.goal_distance_m)
        goal = torch.stack([distance * torch.cos(bearing), distance * torch.sin(bearing),
                            torch.zeros_like(distance)], dim=1)
        put_rows(self.goal_pos_w, slice(None), goal, rows)
        self.engine.mocap_pos[:, 0] = self.goal_pos_w.to(self.engine.mocap_pos.dtype)
        # the chassis has not moved yet: its distance is measured from the reset pose
        put_rows(self._distance[:, None], slice(None), take_rows(self._goal_distance(), rows)[:, None], rows)
        fill_rows(self._progress, rows, 0.0)
        fill_rows(self._reached, rows, False)


register(TaskSpec(
    name="jetbot-goal",
    env_cls=JetbotGoalEnv,
    cfg_fn=jetbot_goal_cfg,
    ppo_cfg_fn=jetbot_goal_ppo,
    description="differential-drive Jetbot drives to a random goal 0.5-1.5 m away (wheel speed actions)",
    success_terminations=("goal_reached",),
    criteria=(Criterion("reaches", min_values={"success_rate": 0.9}),),
))


@dataclass(kw_only=True)
class JetbotGoalVisionCfg(JetbotGoalCfg):
    """jetbot-goal-vision settings: the policy sees the goal through the robot's camera."""

    image_size_px: int = 64
    """Camera image width and height, px."""
    image_pool_px: int = 4
    """The policy gets the rgb image average-pooled over squares of this side (64 / 4: 16 x 16 x 3)."""
    camera_fovy_deg: float = 90.0
    """Vertical field of view, deg (the Jetbot's wide-angle camera sees ~160 deg diagonally)."""
    camera_pitch_deg: float = 20.0
    """Camera tilt below the horizon, deg: the floor from ~5 cm ahead of the robot to the horizon."""
    goal_post_height_m: float = 0.15
    """Height of the goal post (radius ``goal_radius_m``): ~6 px tall at 1.5 m."""


def jetbot_goal_vision_cfg() -> JetbotGoalVisionCfg:
    """jetbot-goal's settings on MuJoCo Warp (what renders the camera)."""
    return JetbotGoalVisionCfg(**{**vars(jetbot_goal_cfg()), "engine": "warp"})


class JetbotGoalVisionEnv(JetbotGoalEnv):
    """jetbot-goal with camera observations; see the module docstring."""

    cfg: JetbotGoalVisionCfg

    def _design_scene(self, spec) -> None:
        cfg = self.cfg
        goal = spec.worldbody.add_body(name="/World/goal", mocap=True, pos=[1.0, 0.0, 0.0])
        half = cfg.goal_post_height_m / 2
        goal.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[cfg.goal_radius_m, half, 0], pos=[0, 0, half],
                      rgba=[0.9, 0.2, 0.2, 1.0], contype=0, conaffinity=0)
        pitch = math.radians(cfg.camera_pitch_deg)
        self.camera = self.sim.add(TiledCamera(TiledCameraCfg(
            prim_path="/World/jetbot/camera_mount/camera", width=cfg.image_size_px, height=cfg.image_size_px,
            fovy_deg=cfg.camera_fovy_deg, offset_quat=(math.cos(pitch / 2), 0.0, math.sin(pitch / 2), 0.0),
            data_types=("rgb",))))

    def _policy_terms(self) -> dict[str, torch.Tensor]:
        terms = super()._policy_terms()
        # the goal's position moves to the critic (``_privileged_terms`` runs right after this)
        self._goal_terms = {name: terms.pop(name) for name in ("goal_pos_b", "goal_distance")}
        rgb = self.camera.data.output["rgb"].permute(0, 3, 1, 2).float()  # (N, 3, H, W)
        image = F.avg_pool2d(rgb, self.cfg.image_pool_px).flatten(1) / 255.0 - 0.5
        return {"image": image, **terms}

    def _privileged_terms(self) -> dict[str, torch.Tensor]:
        return self._goal_terms


register(TaskSpec(
    name="jetbot-goal-vision",
    env_cls=JetbotGoalVisionEnv,
    cfg_fn=jetbot_goal_vision_cfg,
    ppo_cfg_fn=jetbot_goal_ppo,
    description="jetbot-goal seen through the robot's 64x64 camera (TiledCamera on MuJoCo Warp); the critic "
                "alone gets the goal position",
    success_terminations=("goal_reached",),
))
