"""Batched rotation math on torch tensors; quaternions are (w, x, y, z) as in MuJoCo and Isaac."""

from __future__ import annotations

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


def quat_conjugate(quat_wxyz: torch.Tensor) -> torch.Tensor:
    return torch.cat([quat_wxyz[..., :1], -quat_wxyz[..., 1:]], dim=-1)


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


def rotate_yaw_inverse(yaw: torch.Tensor, vec_xy: torch.Tensor) -> torch.Tensor:
    """Express world-frame planar vectors ``vec_xy`` (..., 2) in the heading frame of ``yaw`` (...,)."""
    c, s = torch.cos(yaw), torch.sin(yaw)
    x, y = vec_xy[..., 0], vec_xy[..., 1]
    return torch.stack([c * x + s * y, -s * x + c * y], dim=-1)


def yaw_from_quat(quat_wxyz: torch.Tensor) -> torch.Tensor:
    """Heading angle (rad) about world z of (..., 4) quaternions."""
    w, x, y, z = quat_wxyz.unbind(-1)
    return torch.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quat_from_euler_xyz(roll: torch.Tensor, pitch: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
    """Quaternion of extrinsic x-y-z (roll, pitch, yaw) rotations, i.e. R = Rz Ry Rx."""
    cr, sr = torch.cos(roll / 2), torch.sin(roll / 2)
    cp, sp = torch.cos(pitch / 2), torch.sin(pitch / 2)
    cy, sy = torch.cos(yaw / 2), torch.sin(yaw / 2)
    return torch.stack(
        (
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ),
        dim=-1,
    )


def look_at_quat(eye: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Quaternion of a MuJoCo camera at ``eye`` looking at ``target``, world z up.

    A MuJoCo camera looks along its -z axis with +y up in the image, so the
    camera frame's columns are (right, up, back).
    """
    back = eye - target
    back = back / back.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    world_up = torch.zeros_like(back)
    world_up[..., 2] = 1.0
    right = torch.cross(world_up, back, dim=-1)
    # looking straight up or down: any horizontal right vector will do
    degenerate = right.norm(dim=-1, keepdim=True) < 1e-9
    right = torch.where(degenerate, torch.tensor([1.0, 0.0, 0.0], dtype=back.dtype), right)
    right = right / right.norm(dim=-1, keepdim=True)
    up = torch.cross(back, right, dim=-1)
    return matrix_to_quat(torch.stack((right, up, back), dim=-1))


def matrix_to_quat(mat: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) rotation matrices to (..., 4) unit quaternions (w >= 0)."""
    m = mat
    trace = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]
    candidates = torch.stack(
        (
            torch.stack((1 + trace, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]), -1),
            torch.stack((m[..., 2, 1] - m[..., 1, 2], 1 + m[..., 0, 0] - m[..., 1, 1] - m[..., 2, 2], m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]), -1),
            torch.stack((m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 - m[..., 0, 0] + m[..., 1, 1] - m[..., 2, 2], m[..., 1, 2] + m[..., 2, 1]), -1),
            torch.stack((m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1 - m[..., 0, 0] - m[..., 1, 1] + m[..., 2, 2]), -1),
        ),
        dim=-2,
    )
    # pick the numerically largest of the four equivalent formulas per matrix
    best = candidates.norm(dim=-1).argmax(dim=-1)
    quat = torch.gather(candidates, -2, best[..., None, None].expand(*best.shape, 1, 4)).squeeze(-2)
    quat = quat / quat.norm(dim=-1, keepdim=True)
    return torch.where(quat[..., :1] < 0, -quat, quat)
