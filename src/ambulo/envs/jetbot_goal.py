"""jetbot-goal: drive the two-wheeled Jetbot to a random goal on the floor.

Observations (9): goal position in the base frame (x, y) m, goal distance m, base forward
velocity m/s, yaw rate rad/s, wheel speeds scaled (2), last action (2). Actions (2):
left/right wheel speed targets in units of ``max_wheel_speed_rad_s``, tracked by the
wheels' velocity actuators. Reaching the goal ends the episode as a success.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import torch

from ambulo.core import GroundCfg, PhysicsCfg, RobotCfg
from ambulo.core.rows import fill_rows, put_rows, take_rows

from . import observations as obs_terms
from . import rewards
from .base import EnvCfg, RLEnv
from ..utils.math import quat_from_yaw
from .ppo import PpoCfg
from .registry import Criterion, TaskSpec, register


@dataclass(kw_only=True)
class JetbotGoalCfg(EnvCfg):
    """jetbot-goal settings."""

    max_wheel_speed_rad_s: float = 20.0
    """Wheel speed for an action of 1: 20 rad/s x 0.03 m radius = 0.6 m/s."""
    goal_distance_m: tuple[float, float] = (0.5, 1.5)
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
