"""Batched rotation math on torch tensors; quaternions are (w, x, y, z) as in MuJoCo and Isaac."""

from __future__ import annotations

import numpy as np
import torch


def quat_rotate(quat_wxyz: torch.Tensor, vec: torch.Tensor) -> torch.Tensor:
    """Rotate ``vec`` (..., 3) by unit quaternions ``quat_wxyz`` (..., 4): R(q) v."""
    w = quat_wxyz[..., :1]
    xyz = quat_wxyz[..., 1:]
    t = 2.0 * torch.cross(xyz, vec, dim=-1)
    return vec + w * t + torch.cross(xyz, t, dim=-1)


def quat_rotate_inverse(quat_wxyz: torch.Tensor, vec: torch.Tensor) -> torch.Tensor:
    """Rotate ``vec`` by the inverse of ``quat_wxyz``: R(q)^T v (world -> body frame).

    Same formula as ``quat_rotate`` with w negated, so no conjugate is allocated
    (this runs on every env step).
    """
    w = quat_wxyz[..., :1]
    xyz = quat_wxyz[..., 1:]
    t = 2.0 * torch.cross(xyz, vec, dim=-1)
    return vec - w * t + torch.cross(xyz, t, dim=-1)


def projected_gravity(quat_wxyz: torch.Tensor) -> torch.Tensor:
    """Unit gravity direction (0, 0, -1) of the world expressed in the frame of ``quat_wxyz``,
    (..., 3): upright gives (0, 0, -1), a tilt by theta a z component of -cos(theta)."""
    gravity_w = torch.zeros(quat_wxyz.shape[:-1] + (3,), dtype=quat_wxyz.dtype, device=quat_wxyz.device)
    gravity_w[..., 2] = -1.0
    return quat_rotate_inverse(quat_wxyz, gravity_w)


def quat_mul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Hamilton product a * b of (..., 4) quaternions."""
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack(
        (
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ),
        dim=-1,
    )


def quat_from_axis_angle(axis: torch.Tensor, angle: torch.Tensor) -> torch.Tensor:
    """Unit quaternion (..., 4) of a rotation by ``angle`` (...,) rad about unit ``axis`` (..., 3)."""
    half = 0.5 * angle.unsqueeze(-1)
    return torch.cat([torch.cos(half), axis * torch.sin(half)], dim=-1)


def quat_from_yaw(yaw):
    """Unit quaternions (..., 4) of rotations by ``yaw`` (...,) rad about world z.

    The one yaw-to-quaternion of the package: a tensor gives a tensor; a number or NumPy array
    (host code such as the replicator's scatter) gives a float64 NumPy array, computed with
    NumPy: a frame's few objects cost less than torch's per-call overhead."""
    if not isinstance(yaw, torch.Tensor):
        half = 0.5 * np.asarray(yaw, dtype=np.float64)
        zero = np.zeros_like(half)
        return np.stack([np.cos(half), zero, zero, np.sin(half)], axis=-1)
    half = 0.5 * yaw
    zero = torch.zeros_like(half)
    return torch.stack([torch.cos(half), zero, zero, torch.sin(half)], dim=-1)


def rotate_yaw(yaw: torch.Tensor, vec_xy: torch.Tensor) -> torch.Tensor:
    """Turn planar vectors ``vec_xy`` (..., 2) given in the heading frame of ``yaw`` (...,) into the
    world frame (``rotate_yaw_inverse`` undoes it); the two broadcast against each other."""
    c, s = torch.cos(yaw), torch.sin(yaw)
    x, y = vec_xy[..., 0], vec_xy[..., 1]
    return torch.stack([c * x - s * y, s * x + c * y], dim=-1)


def rotate_yaw_inverse(yaw: torch.Tensor, vec_xy: torch.Tensor) -> torch.Tensor:
    """Express world-frame planar vectors ``vec_xy`` (..., 2) in the heading frame of ``yaw`` (...,)."""
    c, s = torch.cos(yaw), torch.sin(yaw)
    x, y = vec_xy[..., 0], vec_xy[..., 1]
    return torch.stack([c * x + s * y, -s * x + c * y], dim=-1)


def yaw_from_quat(quat_wxyz: torch.Tensor) -> torch.Tensor:
    """Heading angle (rad) about world z of (..., 4) quaternions."""
    w, x, y, z = quat_wxyz.unbind(-1)
    return torch.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
