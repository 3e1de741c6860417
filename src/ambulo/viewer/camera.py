"""The browser's camera: where it starts (the World's viewport camera, so the page and
``ambulo demo``'s video show the same view) and where a world point lands on the page.

The page draws with three.js' perspective camera: a vertical field of view, square pixels, the
principal point at the canvas centre, ``up`` = +z. ``project_w`` is that projection, so a test
(or a user's overlay) can say where on the canvas a simulated point must be drawn.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np


@dataclass(frozen=True)
class CameraPose:
    """A look-at camera: ``eye_w`` and ``target_w`` in the world frame, m; ``fovy_rad`` vertical."""

    eye_w: tuple[float, float, float]
    target_w: tuple[float, float, float]
    fovy_rad: float


def from_mjv_camera(cam: mujoco.MjvCamera, fovy_deg: float) -> CameraPose:
    """The pose of MuJoCo's free camera (``lookat``, ``distance``, ``azimuth``, ``elevation``, deg):
    it looks along (cos el cos az, cos el sin az, sin el) from ``lookat - distance * forward``."""
    az, el = math.radians(cam.azimuth), math.radians(cam.elevation)
    forward = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    target = np.asarray(cam.lookat, dtype=float)
    eye = target - float(cam.distance) * forward
    return CameraPose(eye_w=tuple(eye.tolist()), target_w=tuple(target.tolist()), fovy_rad=math.radians(fovy_deg))


def project_w(points_w, pose: CameraPose, width_px: int, height_px: int) -> np.ndarray:
    """(N, 2) pixel coordinates (x right, y down, from the canvas' top-left corner) of (N, 3)
    world points seen by ``pose`` on a ``width_px`` x ``height_px`` canvas; NaN behind the camera."""
    points_w = np.atleast_2d(np.asarray(points_w, dtype=float))
    eye, target = np.asarray(pose.eye_w), np.asarray(pose.target_w)
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    rel = points_w - eye
    depth = rel @ forward
    focal_px = 0.5 * height_px / math.tan(0.5 * pose.fovy_rad)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = 0.5 * width_px + focal_px * (rel @ right) / depth
        y = 0.5 * height_px - focal_px * (rel @ up) / depth
    out = np.stack([x, y], axis=1)
    out[depth <= 0] = np.nan
    return out
