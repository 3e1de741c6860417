"""Observation terms shared by tasks beyond what ``ambulo.core.EntityData`` reads directly
(projected gravity, base-frame velocities, relative joint positions live there).

Names carry their frame: ``_w`` world, ``_b`` the base (root body) frame, ``_yaw`` the
heading frame (world frame turned by the base's yaw, so z stays vertical). Inputs are
(N, ...) tensors in SI units; outputs keep the inputs' dtype. MuJoCo's free joint stores
its linear velocity in the world frame and its angular velocity in the body frame.
"""

from __future__ import annotations

import torch

from ..utils.math import quat_rotate_inverse, rotate_yaw_inverse, yaw_from_quat


def base_lin_vel_yaw(base_quat_w: torch.Tensor, base_lin_vel_w: torch.Tensor) -> torch.Tensor:
    """Planar velocity of the base in its heading frame, (N, 2) m/s: (forward, left)."""
    return rotate_yaw_inverse(yaw_from_quat(base_quat_w), base_lin_vel_w[..., :2])


def goal_pos_b(base_pos_w: torch.Tensor, base_quat_w: torch.Tensor,
               goal_pos_w: torch.Tensor) -> torch.Tensor:
    """Goal position relative to the base, in the base frame, (N, 3) m."""
    return quat_rotate_inverse(base_quat_w, goal_pos_w - base_pos_w)


__all__ = ["base_lin_vel_yaw", "goal_pos_b"]
