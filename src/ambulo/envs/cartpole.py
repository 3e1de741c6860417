"""cartpole: keep a pole upright by pushing its cart along a rail (the trainer's sanity task).

Observations (4): pole angle (rad, 0 upright), pole angular velocity (rad/s), cart position
(m), cart velocity (m/s). Action (1): cart force in units of ``max_force_n``. The episode
fails when the pole falls past ``max_pole_angle_rad`` or the cart leaves the rail.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import torch

from . import rewards
from .base import EnvCfg, RLEnv
from .registry import register

# A 1 kg cart on a frictionless slider carrying a 1 m, 0.1 kg pole; the force limit in
# the motor keeps any action physically bounded.
CARTPOLE_XML = """
<mujoco model="cartpole">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.01" integrator="implicitfast"/>
  <visual><headlight ambient="0.4 0.4 0.4"/></visual>
  <worldbody>
    <light pos="0 -2 4" dir="0 0.5 -1"/>
    <geom name="floor" type="plane" size="5 2 0.05" rgba="0.2 0.3 0.4 1"/>
    <geom name="rail" type="capsule" fromto="-3 0 1 3 0 1" size="0.015" rgba="0.5 0.5 0.5 1"
          contype="0" conaffinity="0"/>
    <camera name="side" pos="0 -5 1.3" xyaxes="1 0 0 0 0 1"/>
    <body name="cart" pos="0 0 1">
      <joint name="slider" type="slide" axis="1 0 0" range="-3.5 3.5"/>
      <geom name="cart" type="box" size="0.2 0.12 0.08" mass="1" rgba="0.8 0.5 0.2 1"
            contype="0" conaffinity="0"/>
      <body name="pole">
        <joint name="hinge" type="hinge" axis="0 1 0" damping="0.01"/>
        <geom name="pole" type="capsule" fromto="0 0 0 0 0 1" size="0.03" mass="0.1"
              rgba="0.3 0.6 0.9 1" contype="0" conaffinity="0"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="slider" joint="slider" gear="1" forcerange="-100 100"/>
  </actuator>
</mujoco>
"""


@dataclass(kw_only=True)
class CartpoleCfg(EnvCfg):
    """cartpole settings."""

    max_force_n: float = 20.0
    """Cart force for an action of 1, N."""
    max_cart_pos_m: float = 3.0
    """The episode fails when |cart position| exceeds this, m."""
    max_pole_angle_rad: float = 0.5 * torch.pi
    """The episode fails when |pole angle| exceeds this, rad."""
    initial_pole_angle_rad: float = 0.25
    """Initial pole angle is uniform in +-this, rad."""


def cartpole_cfg() -> CartpoleCfg:
    """Default cartpole: 100 Hz physics, 50 Hz policy, 5 s episodes."""
    return CartpoleCfg(
        physics_dt_s=0.01,
        decimation=2,
        episode_length_s=5.0,
        action_clip=1.0,
        reward_weights=dict(
            alive=1.0, terminated=-2.0, pole_angle_l2=-1.0, cart_vel_l1=-0.01, pole_vel_l1=-0.005
        ),
    )


class CartpoleEnv(RLEnv):
    """Cart-pole balancing; see the module docstring."""

    cfg: CartpoleCfg
    num_actions = 1

    def __init__(self, cfg: CartpoleCfg):
        super().__init__(cfg, mujoco.MjModel.from_xml_string(CARTPOLE_XML))

    def _setup(self) -> None:
        self._terminated = torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)

    def _apply_action(self, actions: torch.Tensor) -> None:
        self.engine.ctrl[:, 0] = actions[:, 0] * self.cfg.max_force_n

    def _get_observations(self) -> torch.Tensor:
        qpos, qvel = self.engine.qpos, self.engine.qvel
        return torch.stack([qpos[:, 1], qvel[:, 1], qpos[:, 0], qvel[:, 0]], dim=1).float()

    def _get_terminations(self) -> dict[str, torch.Tensor]:
        qpos = self.engine.qpos
        self._terminated = (qpos[:, 0].abs() > self.cfg.max_cart_pos_m) | (
            qpos[:, 1].abs() > self.cfg.max_pole_angle_rad
        )
        return {"fell": self._terminated}

    def _get_rewards(self) -> dict[str, torch.Tensor]:
        qpos, qvel = self.engine.qpos, self.engine.qvel
        terminated = self._terminated.double()
        return {
            "alive": 1.0 - terminated,
            "terminated": terminated,
            "pole_angle_l2": rewards.l2(qpos[:, 1:2]),
            "cart_vel_l1": qvel[:, 0].abs(),
            "pole_vel_l1": qvel[:, 1].abs(),
        }

    def _reset_idx(self, env_ids: torch.Tensor) -> None:
        a = self.cfg.initial_pole_angle_rad
        self.engine.qpos[env_ids, 1] = self._uniform((len(env_ids),), -a, a)


register("cartpole", CartpoleEnv, cartpole_cfg,
         "balance a pole on a cart (1 action, 4 observations); the trainer's sanity task")
