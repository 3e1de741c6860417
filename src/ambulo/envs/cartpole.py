"""cartpole: keep a pole upright by pushing its cart along a rail (the trainer's sanity task).

The robot is the bundled ``cartpole.urdf``, loaded through the same URDF importer as any
robot of ``add_reference_to_stage``: its two joints arrive as drives, which this task turns
into pure effort joints (zero gains). Observations (4): pole angle (rad, 0 upright), pole
angular velocity (rad/s), cart position (m), cart velocity (m/s). Action (1): cart force in
units of ``max_force_n``. The episode fails when the pole falls past ``max_pole_angle_rad``
or the cart leaves the rail.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from ambulo.core import DriveDefaults, GroundCfg, PhysicsCfg, RobotCfg

from . import rewards
from .base import EnvCfg, RLEnv
from .ppo import PpoCfg
from .registry import Criterion, TaskSpec, register


@dataclass(kw_only=True)
class CartpoleCfg(EnvCfg):
    """cartpole settings."""

    max_force_n: float = 20.0
    """Cart force for an action of 1, N (the URDF's effort limit, 100 N, bounds it too)."""
    max_cart_pos_m: float = 3.0
    """The episode fails when |cart position| exceeds this, m."""
    max_pole_angle_rad: float = 0.5 * math.pi
    """The episode fails when |pole angle| exceeds this, rad."""
    initial_pole_angle_rad: float = 0.25
    """Initial pole angle is uniform in +-this, rad."""


def cartpole_cfg() -> CartpoleCfg:
    """Default cartpole: 100 Hz physics, 50 Hz policy, 5 s episodes."""
    return CartpoleCfg(
        robot=RobotCfg(file="cartpole", prim_path="/World/cartpole", fixed_base=True,
                       drives=DriveDefaults(stiffness=0.0, damping=0.0)),
        ground=GroundCfg(static_friction=1.0, dynamic_friction=1.0, restitution=0.0),
        physics=PhysicsCfg(timestep_s=0.01, integrator="implicitfast", solver_iterations=50),
        decimation=2,
        episode_length_s=5.0,
        action_clip=1.0,
        reward_weights=dict(
            alive=1.0, terminated=-2.0, pole_angle_l2=-1.0, cart_vel_l1=-0.01, pole_vel_l1=-0.005
        ),
    )


def cartpole_ppo() -> PpoCfg:
    """Small nets and short rollouts: cartpole is solved in ~50 iterations."""
    return PpoCfg(num_envs=64, max_iterations=60, num_steps_per_env=32, save_interval=20,
                  actor_hidden_dims=(32, 32), critic_hidden_dims=(32, 32),
                  entropy_coef=0.005, num_mini_batches=2)


class CartpoleEnv(RLEnv):
    """Cart-pole balancing; see the module docstring."""

    cfg: CartpoleCfg

    def _num_actions(self) -> int:
        return 1

    def _setup(self) -> None:
        self.slider, self.hinge = self.robot.find_joints(["slider", "hinge"])
        self._effort = torch.zeros(self.num_envs, self.robot.num_joints, dtype=self.engine.dtype, device=self.device)
        self._zeros = torch.zeros_like(self._effort)
        self._terminated = torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)

    def _apply_action(self, actions: torch.Tensor) -> None:
        self._effort[:, self.slider] = actions[:, 0] * self.cfg.max_force_n
        self.robot.set_joint_targets(self._zeros, effort=self._effort)

    def _policy_terms(self) -> dict[str, torch.Tensor]:
        pos, vel = self.robot.data.joint_pos, self.robot.data.joint_vel
        return {"pole_angle": pos[:, self.hinge:self.hinge + 1], "pole_vel": vel[:, self.hinge:self.hinge + 1],
                "cart_pos": pos[:, self.slider:self.slider + 1], "cart_vel": vel[:, self.slider:self.slider + 1]}

    def _get_terminations(self) -> dict[str, torch.Tensor]:
        pos = self.robot.data.joint_pos
        self._terminated = (pos[:, self.slider].abs() > self.cfg.max_cart_pos_m) | (
            pos[:, self.hinge].abs() > self.cfg.max_pole_angle_rad)
        return {"fell": self._terminated}

    def _get_rewards(self) -> dict[str, torch.Tensor]:
        pos, vel = self.robot.data.joint_pos, self.robot.data.joint_vel
        terminated = self._terminated.float()
        return {
            "alive": 1.0 - terminated,
            "terminated": terminated,
            "pole_angle_l2": rewards.l2(pos[:, self.hinge:self.hinge + 1]),
            "cart_vel_l1": vel[:, self.slider].abs(),
            "pole_vel_l1": vel[:, self.hinge].abs(),
        }

    def _reset_idx(self, rows: torch.Tensor) -> None:
        a = self.cfg.initial_pole_angle_rad
        angle = self._uniform((self._num_rows(rows), 1), -a, a, dtype=self.engine.dtype)
        self.robot.write_joint_state(pos=angle, env_ids=rows, joint_ids=[self.hinge])


register(TaskSpec(
    name="cartpole",
    env_cls=CartpoleEnv,
    cfg_fn=cartpole_cfg,
    ppo_cfg_fn=cartpole_ppo,
    description="balance a pole on a cart (a URDF robot; 1 action, 4 observations); the trainer's sanity task",
    criteria=(Criterion("balances", max_values={"fall_rate": 0.05}),),
))
