"""One RGB-D frame as every part of ``ambulo.perception`` takes it, and the pinhole math on it.

Camera axes are OpenCV's (x right, y down, z forward); ``pose_wc`` maps camera points to the
world (p_w = R p_c + t). Any RGB-D stream fits: ambulo's cameras (``HeadCameraWalk``), Open3D
ray casts, or a user's recorded data with its intrinsics and poses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch

if TYPE_CHECKING:  # named only: the mapper and stereo take frames without loading the odometry
    from .vo.imu import GyroSamples


@dataclass
class RgbdFrame:
    """Depth, optional colour, intrinsics and (optionally) the camera pose of one image."""

    depth_m: torch.Tensor
    """(H, W) float32 depth along the optical axis (z), m; 0 or non-finite where nothing was seen."""
    rgb: torch.Tensor | None
    """(H, W, 3) uint8 colour registered to the depth, or None."""
    intrinsics: torch.Tensor
    """(3, 3) float64 K (pixel centres at integer coordinates)."""
    pose_wc: torch.Tensor | None = None
    """(4, 4) float64 camera-to-world transform (OpenCV axes): ground truth or an estimate."""
    time_s: float = 0.0
    """Timestamp, s."""
    gyro: GyroSamples | None = None
    """The IMU's angular rates from the previous frame's time to this one's, when the stream has an
    IMU (the head-camera walks do); ``RgbdOdometry.track`` takes them."""


def pixel_rays(intrinsics: torch.Tensor, height: int, width: int, device=None) -> torch.Tensor:
    """(H, W, 3) float32 camera-frame directions with z = 1 through every pixel centre."""
    k = intrinsics.to(device=device, dtype=torch.float32)
    v, u = torch.meshgrid(torch.arange(height, device=device, dtype=torch.float32),
                          torch.arange(width, device=device, dtype=torch.float32), indexing="ij")
    return torch.stack([(u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1], torch.ones_like(u)], -1)


def backproject(depth_m: torch.Tensor, intrinsics: torch.Tensor, pose_wc: torch.Tensor | None = None,
                stride: int = 1) -> tuple[torch.Tensor, torch.Tensor]:
    """Points of every ``stride``-th valid depth pixel: (M, 3) float32 in the world (camera frame
    when ``pose_wc`` is None) and their (M,) flat pixel indices into the full image."""
    h, w = depth_m.shape
    rays = pixel_rays(intrinsics, h, w, depth_m.device)[::stride, ::stride]
    depth = depth_m[::stride, ::stride]
    valid = torch.isfinite(depth) & (depth > 0)
    points = rays[valid] * depth[valid, None]
    rows, cols = torch.nonzero(valid, as_tuple=True)
    flat = rows * stride * w + cols * stride
    if pose_wc is not None:
        pose = pose_wc.to(device=depth_m.device, dtype=torch.float32)
        points = points @ pose[:3, :3].T + pose[:3, 3]
    return points, flat


__all__ = ["RgbdFrame", "backproject", "pixel_rays"]
