"""Quaternion helpers for batched env code, MuJoCo convention: q = (w, x, y, z), unit norm.

All functions take and return tensors with a leading batch dimension (N, ...) and
keep the dtype of their inputs (the CPU engine's state is float64).
"""

from __future__ import annotations

import torch


def quat_rotate(quat: torch.Tensor, vec: torch.Tensor) -> torch.Tensor:
    """Rotate ``vec`` (N, 3) by the unit quaternion ``quat`` (N, 4): R(q) v.

    Uses v' = v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z), which avoids
    building rotation matrices.
    """
    w = quat[..., :1]
    u = quat[..., 1:4]
    t = 2.0 * torch.linalg.cross(u, vec, dim=-1)
    return vec + w * t + torch.linalg.cross(u, t, dim=-1)


def quat_rotate_inverse(quat: torch.Tensor, vec: torch.Tensor) -> torch.Tensor:
    """Rotate ``vec`` (N, 3) by the inverse of ``quat`` (N, 4): R(q)^T v (world -> body)."""
    w = quat[..., :1]
    u = quat[..., 1:4]
    t = 2.0 * torch.linalg.cross(u, vec, dim=-1)
    return vec - w * t + torch.linalg.cross(u, t, dim=-1)


def yaw_from_quat(quat: torch.Tensor) -> torch.Tensor:
    """Heading angle (N,) in rad: the rotation about world z of the body's x axis."""
    w, x, y, z = quat.unbind(-1)
    return torch.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quat_from_axis_angle(axis: torch.Tensor, angle: torch.Tensor) -> torch.Tensor:
    """Unit quaternion (N, 4) of a rotation by ``angle`` (N,) rad about unit ``axis`` (N, 3)."""
    half = 0.5 * angle.unsqueeze(-1)
    return torch.cat([torch.cos(half), axis * torch.sin(half)], dim=-1)


def quat_mul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Hamilton product a * b of quaternions (N, 4): rotate by b, then by a."""
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        dim=-1,
    )


def rotate_yaw_inverse(yaw: torch.Tensor, vec_xy: torch.Tensor) -> torch.Tensor:
    """Express world-frame planar vectors ``vec_xy`` (N, 2) in the heading frame of ``yaw`` (N,)."""
    c, s = torch.cos(yaw), torch.sin(yaw)
    x, y = vec_xy[..., 0], vec_xy[..., 1]
    return torch.stack([c * x + s * y, -s * x + c * y], dim=-1)


__all__ = [
    "quat_from_axis_angle",
    "quat_mul",
    "quat_rotate",
    "quat_rotate_inverse",
    "rotate_yaw_inverse",
    "yaw_from_quat",
]
