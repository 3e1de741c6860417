"""Isaac's rotation helpers (``isaacsim.core.utils.rotations``) on NumPy: quaternions (w, x, y, z).

Isaac computes these with SciPy's ``Rotation``; ``extrinsic=True`` is SciPy's ``"xyz"``
(about the fixed x, then y, then z axes: R = Rz Ry Rx) and ``extrinsic=False`` its ``"XYZ"``
(about the moving axes: R = Rx Ry Rz). The same conventions are computed here without SciPy.
"""

from __future__ import annotations

import numpy as np

from ambulo.utils.rotations import mat_to_quat, quat_from_axis_angle, quat_to_mat


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a ⊗ b of (4,) quaternions (w, x, y, z)."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def euler_angles_to_quat(euler_angles, degrees: bool = False, extrinsic: bool = True) -> np.ndarray:
    """(3,) angles about x, y, z (rad, or degrees) -> (4,) quaternion (w, x, y, z), w >= 0."""
    angles = np.asarray(euler_angles, np.float64)
    if angles.shape != (3,):
        raise ValueError(f"euler_angles must be 3 angles (about x, y, z), got shape {angles.shape}")
    if degrees:
        angles = np.radians(angles)
    qx, qy, qz = (quat_from_axis_angle(axis, a) for axis, a in zip(np.eye(3), angles))
    q = _quat_mul(qz, _quat_mul(qy, qx)) if extrinsic else _quat_mul(qx, _quat_mul(qy, qz))
    return -q if q[0] < 0 else q


def quat_to_euler_angles(quat, degrees: bool = False, extrinsic: bool = True) -> np.ndarray:
    """(4,) quaternion (w, x, y, z) -> (3,) angles about x, y, z in the convention above."""
    r = quat_to_mat(np.asarray(quat, np.float64))
    if extrinsic:  # R = Rz(c) Ry(b) Rx(a)
        angles = np.array([np.arctan2(r[2, 1], r[2, 2]), -np.arcsin(np.clip(r[2, 0], -1, 1)),
                           np.arctan2(r[1, 0], r[0, 0])])
    else:  # R = Rx(a) Ry(b) Rz(c)
        angles = np.array([np.arctan2(-r[1, 2], r[2, 2]), np.arcsin(np.clip(r[0, 2], -1, 1)),
                           np.arctan2(-r[0, 1], r[0, 0])])
    return np.degrees(angles) if degrees else angles


def quat_to_rot_matrix(quat) -> np.ndarray:
    """(4,) quaternion (w, x, y, z) -> (3, 3) rotation matrix."""
    return quat_to_mat(quat)


def rot_matrix_to_quat(mat) -> np.ndarray:
    """(3, 3) rotation matrix -> (4,) quaternion (w, x, y, z) with w >= 0."""
    return mat_to_quat(mat)


__all__ = ["euler_angles_to_quat", "quat_to_euler_angles", "quat_to_rot_matrix", "rot_matrix_to_quat"]
