"""Exact depth images of a box scene, ray-cast in torch on any device.

The indoor scenes are oriented boxes (``SolidBox``) on a floor slab, so a pinhole camera's depth is
exact with the slab test (Kay & Kajiya 1986) per box: no mesh, no renderer, no Open3D. Used where
Open3D's ``RaycastingScene`` (``reference.TruthScene``) is not installed, e.g. on a GPU machine that
times the mapper; the tests check the two agree.
"""

from __future__ import annotations

import numpy as np
import torch

from ambulo.scenes.indoor import SolidBox, with_floor

from .frames import RgbdFrame


def box_depth(solids: list[SolidBox], intrinsics, pose_wc, width: int, height: int, *,
              floor_half_m: float | None = 6.0, device: torch.device | str = "cpu") -> torch.Tensor:
    """(H, W) float32 z-depth, m, of the first box each pixel's ray meets (0: none).

    Pixel (u, v) looks along ``K^-1 [u, v, 1]`` (pixel centres at whole coordinates, as
    ``reference.TruthScene``). That direction has camera z = 1, so the ray parameter of a hit is its
    z-depth. ``pose_wc``: (4, 4) camera-to-world, OpenCV axes."""
    k = torch.as_tensor(np.asarray(intrinsics, np.float64), device=device)
    pose = torch.as_tensor(np.asarray(pose_wc, np.float64), device=device)
    v, u = torch.meshgrid(torch.arange(height, device=device, dtype=torch.float64),
                          torch.arange(width, device=device, dtype=torch.float64), indexing="ij")
    rays_c = torch.stack([(u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1], torch.ones_like(u)], -1).reshape(-1, 3)
    dirs_w = rays_c @ pose[:3, :3].T  # (N, 3), camera z component 1
    origin_w = pose[:3, 3]
    nearest = torch.full((dirs_w.shape[0],), torch.inf, dtype=torch.float64, device=device)
    for box in with_floor(solids, floor_half_m):
        rot = torch.as_tensor(box.rotation(), device=device)
        half = torch.as_tensor(box.half_m, dtype=torch.float64, device=device)
        origin_b = (origin_w - torch.as_tensor(box.center_m, dtype=torch.float64, device=device)) @ rot  # (3,)
        dirs_b = dirs_w @ rot  # (N, 3) in the box's axes
        with torch.no_grad():
            inv = 1.0 / dirs_b  # +-inf along an axis the ray is parallel to: that slab is all or nothing
            t1, t2 = (-half - origin_b) * inv, (half - origin_b) * inv
            near = torch.minimum(t1, t2).nan_to_num(nan=-torch.inf).amax(-1)
            far = torch.maximum(t1, t2).nan_to_num(nan=torch.inf).amin(-1)
        hit = (near <= far) & (near > 0)  # the camera is never inside a box
        nearest = torch.where(hit & (near < nearest), near, nearest)
    return torch.where(torch.isfinite(nearest), nearest, torch.zeros_like(nearest)).reshape(height, width).float()


def raycast_frames(solids: list[SolidBox], poses: np.ndarray, intrinsics, width: int, height: int, *,
                   noise_seed: int | None = 0, noise_coeff: float = 0.002,
                   device: torch.device | str = "cpu") -> list[RgbdFrame]:
    """``reference.truth_frames`` without Open3D: exact depth plus noise sigma = coeff * z^2 (the
    same NumPy noise stream for the same seed), grey colour from depth; tensors on ``device``."""
    rng = None if noise_seed is None else np.random.default_rng(noise_seed)
    frames = []
    for i, pose in enumerate(poses):
        depth = box_depth(solids, intrinsics, pose, width, height, device=device)
        if rng is not None:
            noise = torch.as_tensor(rng.normal(0, 1, depth.shape), device=device)
            depth = torch.where(depth > 0, depth + noise * noise_coeff * depth * depth, 0.0).float()
        grey = (depth * 50).clamp(0, 255).to(torch.uint8)
        frames.append(RgbdFrame(depth_m=depth, rgb=grey[..., None].expand(-1, -1, 3).contiguous(),
                                intrinsics=torch.as_tensor(np.asarray(intrinsics, np.float64)),
                                pose_wc=torch.as_tensor(np.asarray(pose, np.float64)), time_s=i / 30.0))
    return frames


__all__ = ["box_depth", "raycast_frames"]
