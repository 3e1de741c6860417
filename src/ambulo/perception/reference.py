"""Independent references for ``ambulo.perception``, all from Open3D (the ``perception`` extra):
exact synthetic depth from ``RaycastingScene``, its point-to-mesh distance as ground truth, and
Open3D's own ``VoxelBlockGrid`` TSDF to compare our map with on identical frames.

Tests, benchmarks and ``ambulo map`` use these; the mapper itself never imports Open3D.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import torch

from ambulo.scenes.indoor import SolidBox, with_floor

from .frames import RgbdFrame


def _o3d():
    import open3d as o3d  # optional (perception extra), imported when used
    return o3d


def box_meshes(solids: list[SolidBox], floor_half_m: float | None = 6.0):
    """Open3D legacy triangle meshes of the boxes (and a floor slab top at z = 0 if asked)."""
    o3d = _o3d()
    meshes = []
    for box in with_floor(solids, floor_half_m):
        half = np.asarray(box.half_m, float)
        mesh = o3d.geometry.TriangleMesh.create_box(*(2 * half))
        mesh.translate(-half)
        mesh.rotate(box.rotation(), center=(0, 0, 0))
        mesh.translate(np.asarray(box.center_m, float))
        meshes.append(mesh)
    return meshes


class TruthScene:
    """Exact geometry of a box scene: ray-cast depth and distance to the true surface."""

    def __init__(self, solids: list[SolidBox], floor_half_m: float | None = 6.0):
        o3d = _o3d()
        self.scene = o3d.t.geometry.RaycastingScene()
        for mesh in box_meshes(solids, floor_half_m):
            self.scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))

    def depth(self, intrinsics: np.ndarray, pose_wc: np.ndarray, width: int, height: int,
              noise_rng: np.random.Generator | None = None, noise_coeff: float = 0.002) -> np.ndarray:
        """(H, W) float32 z-depth, m (0 where no hit); optional noise sigma = coeff * z^2 (Kinect-like,
        the model of research/anchors-perception-nav.md 1.3)."""
        o3d = _o3d()
        extrinsic = np.linalg.inv(pose_wc)
        # Open3D casts pixel (u, v)'s ray through (u + 0.5, v + 0.5); K here (OpenCV, as the mappers
        # use it: cx = W / 2 - 0.5) puts pixel centres at whole coordinates, so shift the principal point
        # half a pixel: without it every frame was rendered half a pixel off the intrinsics it came with
        k = np.asarray(intrinsics, np.float64).copy()
        k[0, 2] += 0.5
        k[1, 2] += 0.5
        rays = self.scene.create_rays_pinhole(o3d.core.Tensor(k), o3d.core.Tensor(extrinsic), width, height)
        t_hit = self.scene.cast_rays(rays)["t_hit"].numpy()
        dirs = rays.numpy()[..., 3:]
        # t_hit is along the (unnormalised) ray direction; z-depth is t * (direction . optical axis)
        z = t_hit * (dirs @ pose_wc[:3, 2])
        z = np.where(np.isfinite(z), z, 0.0).astype(np.float32)
        if noise_rng is not None:
            z = np.where(z > 0, z + noise_rng.normal(0, 1, z.shape) * noise_coeff * z * z, 0).astype(np.float32)
        return z

    def distance(self, points_w: np.ndarray) -> np.ndarray:
        """(N,) unsigned distance of world points to the true surface, m."""
        o3d = _o3d()
        return self.scene.compute_distance(o3d.core.Tensor(np.asarray(points_w, np.float32))).numpy()


def orbit_poses(center, radius_m: float, height_m: float, count: int, turns: float = 1.0) -> np.ndarray:
    """(count, 4, 4) camera-to-world poses (OpenCV axes) on a circle looking at ``center``."""
    poses = []
    c = np.asarray(center, float)
    for i in range(count):
        a = 2 * math.pi * turns * i / count
        eye = c + np.array([radius_m * math.cos(a), radius_m * math.sin(a), height_m])
        z = c - eye
        z /= np.linalg.norm(z)
        x = np.cross(z, [0.0, 0.0, 1.0])
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        pose = np.eye(4)
        pose[:3, :3] = np.stack([x, y, z], -1)
        pose[:3, 3] = eye
        poses.append(pose)
    return np.array(poses)


def truth_frames(truth: TruthScene, poses: np.ndarray, intrinsics: np.ndarray, width: int, height: int,
                 noise_seed: int | None = 0) -> list[RgbdFrame]:
    """Ray-cast depth frames (grey colour from depth, for the colour channel) at ``poses``."""
    rng = None if noise_seed is None else np.random.default_rng(noise_seed)
    frames = []
    for i, pose in enumerate(poses):
        depth = truth.depth(intrinsics, pose, width, height, rng)
        grey = np.clip(depth * 50, 0, 255).astype(np.uint8)
        frames.append(RgbdFrame(depth_m=torch.from_numpy(depth), rgb=torch.from_numpy(np.repeat(grey[..., None], 3, -1)),
                                intrinsics=torch.from_numpy(np.asarray(intrinsics, np.float64)),
                                pose_wc=torch.from_numpy(np.asarray(pose, np.float64)), time_s=i / 30.0))
    return frames


@dataclass
class Open3dTsdfResult:
    vertices: np.ndarray
    """(V, 3) float mesh vertices, m."""
    integrate_ms: list[float]
    """Per-frame block allocation + integration time, ms."""
    mesh_ms: float


def open3d_tsdf(frames: list[RgbdFrame], voxel_size_m: float, truncation_voxels: float, depth_max_m: float,
                block_voxels: int = 8, weight_threshold: float = 1.0) -> Open3dTsdfResult:
    """Open3D's ``VoxelBlockGrid`` (CPU) on ``frames``: the reference TSDF, timed per frame."""
    o3d = _o3d()
    device = o3d.core.Device("CPU:0")
    vbg = o3d.t.geometry.VoxelBlockGrid(attr_names=("tsdf", "weight", "color"),
                                        attr_dtypes=(o3d.core.float32, o3d.core.float32, o3d.core.float32),
                                        attr_channels=((1), (1), (3)), voxel_size=voxel_size_m,
                                        block_resolution=block_voxels, block_count=50000, device=device)
    times = []
    for frame in frames:
        depth = o3d.t.geometry.Image(o3d.core.Tensor(np.ascontiguousarray(frame.depth_m.numpy())))
        color = o3d.t.geometry.Image(o3d.core.Tensor(np.ascontiguousarray(frame.rgb.numpy().astype(np.float32))))
        k = o3d.core.Tensor(frame.intrinsics.numpy().astype(np.float64))
        extrinsic = o3d.core.Tensor(np.linalg.inv(frame.pose_wc.numpy()))
        t0 = time.perf_counter()
        coords = vbg.compute_unique_block_coordinates(depth, k, extrinsic, 1.0, depth_max_m, truncation_voxels)
        vbg.integrate(coords, depth, color, k, extrinsic, 1.0, depth_max_m, truncation_voxels)
        times.append((time.perf_counter() - t0) * 1e3)
    t0 = time.perf_counter()
    mesh = vbg.extract_triangle_mesh(weight_threshold=weight_threshold)
    mesh_ms = (time.perf_counter() - t0) * 1e3
    return Open3dTsdfResult(mesh.vertex.positions.numpy(), times, mesh_ms)


__all__ = ["Open3dTsdfResult", "TruthScene", "box_meshes", "open3d_tsdf", "orbit_poses", "truth_frames"]
