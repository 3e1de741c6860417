"""WheeledRobot and DifferentialController (Isaac's wheeled-robot API)."""

from __future__ import annotations

import torch

from .actions import ArticulationAction
from .articulation import Robot
from .stage import add_reference_to_stage


class WheeledRobot(Robot):
    """A robot whose named wheel joints are velocity-driven.

    Args:
      wheel_dof_names: the wheel joints, e.g. ``["left_wheel_joint", "right_wheel_joint"]``.
      create_robot: reference ``usd_path`` (USD, URDF or MJCF) at ``prim_path`` first.
    """

    def __init__(self, prim_path: str, name: str | None = None, wheel_dof_names=None,
                 wheel_dof_indices=None, create_robot: bool = False, usd_path: str | None = None,
                 position=None, orientation=None):
        if create_robot:
            if usd_path is None:
                raise ValueError("create_robot=True needs usd_path= (a USD, URDF or MJCF file)")
            add_reference_to_stage(usd_path=usd_path, prim_path=prim_path)
        if wheel_dof_names is None and wheel_dof_indices is None:
            raise ValueError("give wheel_dof_names= (e.g. ['left_wheel_joint', 'right_wheel_joint'])")
        super().__init__(prim_path, name, position, orientation)
        self._wheel_dof_names = None if wheel_dof_names is None else list(wheel_dof_names)
        self._wheel_dof_indices = wheel_dof_indices

    def initialize(self, world) -> None:
        super().initialize(world)
        if self._wheel_dof_names is not None:
            self._wheel_dof_indices = [self.get_dof_index(n) for n in self._wheel_dof_names]
        self._wheel_idx = self._indices(self._wheel_dof_indices)
        # wheels track velocity: no stiffness on them
        self.get_articulation_controller().switch_control_mode("velocity", self._wheel_idx)

    @property
    def wheel_dof_indices(self) -> list[int]:
        return self._wheel_idx.tolist()

    def apply_wheel_actions(self, actions: ArticulationAction) -> None:
        """Apply wheel velocities (rad/s) / efforts given in wheel order."""
        self.apply_action(ArticulationAction(
            joint_positions=actions.joint_positions, joint_velocities=actions.joint_velocities,
            joint_efforts=actions.joint_efforts, joint_indices=self._wheel_idx))

    def get_wheel_positions(self):
        return self.get_joint_positions(self._wheel_idx)

    def get_wheel_velocities(self):
        return self.get_joint_velocities(self._wheel_idx)

    def set_wheel_positions(self, positions) -> None:
        """Teleport the wheel joints to ``positions`` (rad, wheel order), as Isaac does."""
        self.set_joint_positions(positions, self._wheel_idx)

    def set_wheel_velocities(self, velocities) -> None:
        """Set the wheel joints' velocities (rad/s, wheel order) now; the drives keep their
        targets, so use ``apply_wheel_actions`` to keep the wheels turning."""
        self.set_joint_velocities(velocities, self._wheel_idx)


class DifferentialController:
    """Unicycle command (v m/s, w rad/s) -> (left, right) wheel speeds (rad/s).

    w_left = (v - w b / 2) / r and w_right = (v + w b / 2) / r for wheel radius r
    and wheel base b; optional limits clip the command first.
    """

    def __init__(self, name: str = "differential_controller", wheel_radius: float = 0.03,
                 wheel_base: float = 0.1125, max_linear_speed: float = float("inf"),
                 max_angular_speed: float = float("inf"), max_wheel_speed: float = float("inf")):
        if wheel_radius <= 0 or wheel_base <= 0:
            raise ValueError("wheel_radius and wheel_base must be > 0 (metres)")
        self.name = name
        self.wheel_radius, self.wheel_base = float(wheel_radius), float(wheel_base)
        self.max_linear_speed, self.max_angular_speed = max_linear_speed, max_angular_speed
        self.max_wheel_speed = max_wheel_speed

    def forward(self, command) -> ArticulationAction:
        """``command`` = [v, w] or (N, 2); returns wheel velocities (.., 2)."""
        cmd = torch.as_tensor(command, dtype=torch.float64)
        if cmd.shape[-1:] != (2,) or cmd.dim() > 2:
            raise ValueError(f"command must be [linear m/s, angular rad/s] or (N, 2); got shape {tuple(cmd.shape)}")
        if torch.isnan(cmd).any():
            raise ValueError("command contains NaN")
        v = cmd[..., 0].clamp(-self.max_linear_speed, self.max_linear_speed)
        w = cmd[..., 1].clamp(-self.max_angular_speed, self.max_angular_speed)
        half = 0.5 * self.wheel_base
        wheels = torch.stack(((v - w * half) / self.wheel_radius, (v + w * half) / self.wheel_radius), -1)
        wheels = wheels.clamp(-self.max_wheel_speed, self.max_wheel_speed)
        return ArticulationAction(joint_velocities=wheels.numpy())

    def reset(self) -> None:
        """Isaac's controller API; this controller keeps no state between calls."""
