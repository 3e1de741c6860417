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

from ambulo import assets

from . import observations as obs_terms
from . import rewards
from .base import EnvCfg, RLEnv
from ..utils.math import quat_from_axis_angle
from .registry import register
from .robot import PdRobot
from .scene import ROBOT_PREFIX, scene_spec


@dataclass(kw_only=True)
class JetbotGoalCfg(EnvCfg):
    """jetbot-goal settings."""

    robot_file: str | None = None
    """Robot MJCF; None is the bundled ``jetbot``."""
    base_body: str = "chassis"
    max_wheel_speed_rad_s: float = 20.0
    """Wheel speed for an action of 1: 20 rad/s x 0.03 m radius = 0.6 m/s."""
    goal_distance_m: tuple[float, float] = (0.5, 1.5)
    goal_radius_m: float = 0.1
    """The goal counts as reached within this distance of the chassis origin, m."""
    obs_scale_wheel_vel: float = 0.05


def jetbot_goal_cfg() -> JetbotGoalCfg:
    """Default jetbot-goal: 200 Hz physics, 20 Hz policy, 10 s episodes."""
    return JetbotGoalCfg(
        physics_dt_s=0.005,
        decimation=10,
        episode_length_s=10.0,
        action_clip=1.0,
        reward_weights=dict(progress=2.0, goal_reached=200.0, action_rate_l2=-0.01),
    )


class JetbotGoalEnv(RLEnv):
    """Goal reaching with a differential drive; see the module docstring."""

    cfg: JetbotGoalCfg
    success_terminations = ("goal_reached",)

    def __init__(self, cfg: JetbotGoalCfg):
        spec = scene_spec(cfg.robot_file or assets.path("jetbot"))
        goal = spec.worldbody.add_body(name="goal", mocap=True, pos=[1.0, 0.0, 0.0])
        goal.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[cfg.goal_radius_m, 0.002, 0],
                      rgba=[0.9, 0.2, 0.2, 0.6], contype=0, conaffinity=0)
        model = spec.compile()
        self.robot = PdRobot(model, ROBOT_PREFIX + cfg.base_body, {}, ROBOT_PREFIX)
        self.num_actions = self.robot.num_joints
        super().__init__(cfg, model)

    def _setup(self) -> None:
        n, dev = self.num_envs, self.device
        self.robot.to_device(dev)
        self.goal_pos_w = torch.zeros(n, 3, dtype=torch.float64, device=dev)
        """(N, 3) goal position in the world frame, m."""
        self._distance = torch.zeros(n, dtype=torch.float64, device=dev)
        self._progress = torch.zeros_like(self._distance)
        self._reached = torch.zeros(n, dtype=torch.bool, device=dev)
        self._wheel_speed_gain = torch.as_tensor(
            self.robot.kd * self.cfg.max_wheel_speed_rad_s, dtype=torch.float64, device=dev)

    def _goal_distance(self) -> torch.Tensor:
        base_xy = self.engine.qpos[:, self.robot.pos_slice][:, :2]
        return torch.linalg.vector_norm(self.goal_pos_w[:, :2] - base_xy, dim=-1)

    def _apply_action(self, actions: torch.Tensor) -> None:
        # velocity actuators (KP = 0): ctrl = KD * w_target gives tau = KD (w_target - w)
        torch.mul(actions, self._wheel_speed_gain, out=self.engine.ctrl)

    def _post_physics(self) -> None:
        distance = self._goal_distance()
        self._progress = (self._distance - distance) / self.step_dt_s
        self._distance = distance

    def _get_observations(self) -> torch.Tensor:
        robot, qpos, qvel = self.robot, self.engine.qpos, self.engine.qvel
        quat = robot.base_quat_w(self.engine)
        goal_b = obs_terms.goal_pos_b(qpos[:, robot.pos_slice], quat, self.goal_pos_w)
        vel_b = obs_terms.base_lin_vel_b(quat, qvel[:, robot.lin_vel_slice])
        return torch.cat(
            [
                goal_b[:, :2],
                self._distance.unsqueeze(1),
                vel_b[:, :1],
                qvel[:, robot.ang_vel_slice][:, 2:3],
                robot.joint_vel(self.engine) * self.cfg.obs_scale_wheel_vel,
                self.actions,
            ],
            dim=1,
        ).float()

    def _get_terminations(self) -> dict[str, torch.Tensor]:
        self._reached = self._distance < self.cfg.goal_radius_m
        gravity_b = obs_terms.projected_gravity_b(self.robot.base_quat_w(self.engine))
        return {"goal_reached": self._reached, "flipped": rewards.upright(gravity_b) < 0.5}

    def _get_rewards(self) -> dict[str, torch.Tensor]:
        return {
            "progress": self._progress,
            "goal_reached": self._reached.double(),
            "action_rate_l2": rewards.action_rate_l2(self.actions, self.prev_actions),
        }

    def _reset_idx(self, env_ids: torch.Tensor) -> None:
        n, cfg = len(env_ids), self.cfg
        z_axis = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64, device=self.device).expand(n, 3)
        yaw = self._uniform((n,), -math.pi, math.pi)
        self.robot.write_base_quat(self.engine, env_ids, quat_from_axis_angle(z_axis, yaw))
        bearing = self._uniform((n,), -math.pi, math.pi)
        distance = self._uniform((n,), *cfg.goal_distance_m)
        goal = torch.stack([distance * torch.cos(bearing), distance * torch.sin(bearing),
                            torch.zeros_like(distance)], dim=1)
        self.goal_pos_w[env_ids] = goal
        self.engine.mocap_pos[env_ids, 0] = goal
        self._distance[env_ids] = self._goal_distance()[env_ids]
        self._progress[env_ids] = 0.0
        self._reached[env_ids] = False


register("jetbot-goal", JetbotGoalEnv, jetbot_goal_cfg,
         "differential-drive Jetbot drives to a random goal 0.5-1.5 m away (wheel speed actions)")
