"""Camera axis conventions and look-at (NumPy, float64, batched over leading dims).

Rotation math (quaternions (w, x, y, z) as in MuJoCo and Isaac) lives in
``ambulo.utils.rotations``. Camera conventions name the camera axes a rotation refers to:

- ``"opengl"`` (MuJoCo, USD): x right, y up, looking along -z;
- ``"opencv"`` (also ``"ros"`` optical frame): x right, y down, looking along +z;
- ``"world"`` (Isaac's default for camera poses): x forward, y left, z up.
"""

from __future__ import annotations

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
    # looking straight along `up` leaves x undefined: fall back to world y as the up hint
    degenerate = np.linalg.norm(x, axis=-1, keepdims=True) < 1e-9
    x = np.where(degenerate, np.cross(np.broadcast_to([0.0, 1.0, 0.0], z.shape), z), x)
    x = x / np.linalg.norm(x, axis=-1, keepdims=True)
    y = np.cross(z, x)
    return np.stack([x, y, z], -1)
