"""Isaac Sim's three camera-axes conventions for camera poses, as rotations of the USD camera axes.

Isaac's ``Camera.get_world_pose(camera_axes=...)`` and its setters describe the camera frame in
one of three conventions (``isaacsim.sensors.camera.camera``: ``W_U_TRANSFORM``,
``R_U_TRANSFORM``):

- ``"world"`` (robotics; Isaac's default): +X forward, +Y left, +Z up;
- ``"ros"`` (computer vision / ROS optical frame): +Z forward, +X right, -Y up;
- ``"usd"`` (computer graphics, = OpenGL / MuJoCo camera): -Z forward, +X right, +Y up.

The camera itself is stored as its USD (OpenGL) axes: ``R_w_usd = R_w_axes @ USD_IN[axes]``.
Quaternions are (w, x, y, z); arrays are NumPy float64.
"""

from __future__ import annotations

import numpy as np

from ambulo.sensors.frames import GL_IN
from ambulo.utils.rotations import mat_to_quat, quat_to_mat

CAMERA_AXES = ("world", "ros", "usd")

USD_IN = {"world": GL_IN["world"], "ros": GL_IN["ros"], "usd": GL_IN["opengl"]}
"""Columns: the USD camera axes expressed in each convention's axes (3, 3)."""


def check_axes(camera_axes: str) -> np.ndarray:
    """The (3, 3) USD-in-``camera_axes`` matrix; a one-line error naming the accepted values."""
    if camera_axes not in USD_IN:
        raise ValueError(f"camera_axes {camera_axes!r} is not supported; pass one of {list(CAMERA_AXES)}")
    return USD_IN[camera_axes]


def rot_to_usd(rot: np.ndarray, camera_axes: str) -> np.ndarray:
    """(..., 3, 3) camera axes in ``camera_axes`` convention -> the same camera's USD axes."""
    return np.asarray(rot, np.float64) @ check_axes(camera_axes)


def rot_from_usd(rot_usd: np.ndarray, camera_axes: str) -> np.ndarray:
    """(..., 3, 3) USD camera axes -> the same camera's axes in ``camera_axes`` convention."""
    return np.asarray(rot_usd, np.float64) @ check_axes(camera_axes).T


def quat_to_usd(quat: np.ndarray, camera_axes: str) -> np.ndarray:
    """(..., 4) wxyz orientation of a camera in ``camera_axes`` -> wxyz of its USD axes."""
    return mat_to_quat(rot_to_usd(quat_to_mat(quat), camera_axes))


def quat_from_usd(quat_usd: np.ndarray, camera_axes: str) -> np.ndarray:
    """(..., 4) wxyz of a camera's USD axes -> wxyz of the camera in ``camera_axes``."""
    return mat_to_quat(rot_from_usd(quat_to_mat(quat_usd), camera_axes))


__all__ = ["CAMERA_AXES", "USD_IN", "check_axes", "quat_from_usd", "quat_to_usd", "rot_from_usd", "rot_to_usd"]
