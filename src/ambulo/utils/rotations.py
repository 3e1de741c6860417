"""Rotation math on NumPy arrays (float64, batched over leading dims) for host-side work:
building scenes, placing cameras and sensors, generating data. Quaternions are (w, x, y, z)
as in MuJoCo and Isaac. The torch versions for batched engine state on any device are in
``ambulo.utils.math``.
"""

from __future__ import annotations

import mujoco
import numpy as np


def quat_to_mat(quat_wxyz: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions -> (..., 3, 3) rotation matrices."""
    q = np.asarray(quat_wxyz, np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    if q.ndim == 1:  # one quaternion: the same arithmetic on Python floats, ~10x faster than stacking
        w, x, y, z = q.tolist()
        return np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ])
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def mat_to_quat(mat: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 4) quaternions with w >= 0."""
    m = np.asarray(mat, np.float64)
    if m.ndim == 2:  # one matrix: MuJoCo's C routine is ~20x faster than the batched path
        q = np.empty(4)
        mujoco.mju_mat2Quat(q, m.ravel())
        return -q if q[0] < 0 else q
    # Shepperd's method: take the largest of the four squared components for stability.
    t = np.stack([
        1 + m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2],
        1 + m[..., 0, 0] - m[..., 1, 1] - m[..., 2, 2],
        1 - m[..., 0, 0] + m[..., 1, 1] - m[..., 2, 2],
        1 - m[..., 0, 0] - m[..., 1, 1] + m[..., 2, 2],
    ], -1)
    k = np.argmax(t, axis=-1)
    s = np.sqrt(np.maximum(np.take_along_axis(t, k[..., None], -1)[..., 0], 1e-300)) * 2
    d = {
        "w": m[..., 2, 1] - m[..., 1, 2], "x": m[..., 0, 2] - m[..., 2, 0],
        "y": m[..., 1, 0] - m[..., 0, 1],
        "xy": m[..., 0, 1] + m[..., 1, 0], "xz": m[..., 0, 2] + m[..., 2, 0],
        "yz": m[..., 1, 2] + m[..., 2, 1],
    }
    cands = np.stack([
        np.stack([s / 4, d["w"] / s, d["x"] / s, d["y"] / s], -1),
        np.stack([d["w"] / s, s / 4, d["xy"] / s, d["xz"] / s], -1),
        np.stack([d["x"] / s, d["xy"] / s, s / 4, d["yz"] / s], -1),
        np.stack([d["y"] / s, d["xz"] / s, d["yz"] / s, s / 4], -1),
    ], -2)
    q = np.take_along_axis(cands, k[..., None, None], -2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def quat_from_axis_angle(axis, angle) -> np.ndarray:
    """(..., 4) unit quaternions of rotations by ``angle`` (...,) rad about unit ``axis`` (..., 3)."""
    half = np.asarray(angle, np.float64)[..., None] / 2
    return np.concatenate([np.cos(half), np.asarray(axis, np.float64) * np.sin(half)], -1)


def rot_about_axes(rotvec: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vectors (axis * angle, rad) -> (..., 3, 3) (Rodrigues)."""
    v = np.asarray(rotvec, np.float64)
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    axis = v / np.maximum(angle, 1e-300)
    return quat_to_mat(quat_from_axis_angle(axis, angle[..., 0]))
