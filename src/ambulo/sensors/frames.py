"""Rotation helpers and camera axis conventions (NumPy, float64, batched over leading dims).

Quaternions are (w, x, y, z) as in MuJoCo and Isaac. Camera conventions name
the camera axes a rotation refers to:

- ``"opengl"`` (MuJoCo, USD): x right, y up, looking along -z;
- ``"opencv"`` (also ``"ros"`` optical frame): x right, y down, looking along +z;
- ``"world"`` (Isaac's default for camera poses): x forward, y left, z up.
"""

from __future__ import annotations

import mujoco
import numpy as np

# Columns: the OpenGL camera axes expressed in each convention's axes, so that
# R_w_gl = R_w_conv @ GL_IN[conv].
GL_IN = {
    "opengl": np.eye(3),
    "opencv": np.diag([1.0, -1.0, -1.0]),
    "ros": np.diag([1.0, -1.0, -1.0]),
    "world": np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
}


def check_convention(convention: str) -> np.ndarray:
    try:
        return GL_IN[convention]
    except KeyError:
        raise ValueError(
            f"unknown camera convention {convention!r}; use one of {sorted(GL_IN)}"
        ) from None


def quat_to_mat(quat_wxyz: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions -> (..., 3, 3) rotation matrices."""
    q = np.asarray(quat_wxyz, np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
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


def look_at_gl(eye: np.ndarray, target: np.ndarray, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """(..., 3, 3) OpenGL camera axes in the world for a camera at ``eye`` looking at ``target``."""
    eye, target = np.asarray(eye, np.float64), np.asarray(target, np.float64)
    back = eye - target
    norm = np.linalg.norm(back, axis=-1, keepdims=True)
    if np.any(norm < 1e-9):
        raise ValueError("set_camera_view: eye and target coincide; move the eye away from the target")
    z = back / norm
    up = np.broadcast_to(np.asarray(up, np.float64), z.shape)
    x = np.cross(up, z)
    # looking straight along `up` leaves x undefined: fall back to world x as the up hint
    degenerate = np.linalg.norm(x, axis=-1, keepdims=True) < 1e-9
    x = np.where(degenerate, np.cross(np.broadcast_to([0.0, 1.0, 0.0], z.shape), z), x)
    x = x / np.linalg.norm(x, axis=-1, keepdims=True)
    y = np.cross(z, x)
    return np.stack([x, y, z], -1)


def rot_about_axes(rotvec: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vectors (axis * angle, rad) -> (..., 3, 3) (Rodrigues)."""
    v = np.asarray(rotvec, np.float64)
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    axis = v / np.maximum(angle, 1e-300)
    half = angle / 2
    quat = np.concatenate([np.cos(half), axis * np.sin(half)], -1)
    return quat_to_mat(quat)
