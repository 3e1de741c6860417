"""Height above the floor of every pixel of a depth image, from the camera's pose.

Conventions: OpenCV camera (x right, y down, z forward); ``intrinsics`` K (3, 3) with pixel centres at
integer coordinates (the cameras' and ``replicator``'s: cx = (W - 1) / 2); ``extrinsics_cw`` (4, 4) world ->
camera; world z up, the floor at ``floor_z_m``. Depth is z along the optical axis (m); 0 or NaN is no return,
whose height is 0. ``ambulo.detection.height`` says why a detector wants it.
"""

from __future__ import annotations

import numpy as np


def height_above_floor_m(depth_m: np.ndarray, intrinsics: np.ndarray, extrinsics_cw: np.ndarray,
                         floor_z_m: float = 0.0) -> np.ndarray:
    """(H, W) float32 height above the floor (m) of each pixel's point, from ``depth_m`` (H, W) m and the
    camera (module docstring); pixels without a return are 0."""
    depth = np.nan_to_num(np.asarray(depth_m, np.float64), nan=0.0, posinf=0.0)
    h, w = depth.shape
    k = np.asarray(intrinsics, np.float64)
    t_cw = np.asarray(extrinsics_cw, np.float64)
    # world z of camera point p: (R_cw^T (p - t))_z = r . p - r . t, r the third column of R_cw
    r = t_cw[:3, 2]
    up_per_px = r @ np.linalg.inv(k)  # (3,): r . K^-1 (u, v, 1), per unit depth
    v, u = np.mgrid[0:h, 0:w]
    along = up_per_px[0] * u + up_per_px[1] * v + up_per_px[2]  # (H, W)
    height = depth * along - r @ t_cw[:3, 3] - floor_z_m
    return np.where(depth > 0, height, 0.0).astype(np.float32)


__all__ = ["height_above_floor_m"]
