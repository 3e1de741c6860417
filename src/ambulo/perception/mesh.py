"""Meshes of a ``TsdfMap``: marching cubes (Lorensen & Cline 1987, scikit-image's implementation)
on the zero level of the TSDF, over voxels observed with enough weight, coloured by the nearest
voxel; incrementally, only the blocks that changed since the last extraction are re-meshed
(nvblox's and voxblox's mesh-per-block scheme). PLY writing for people to look at the result.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from .tsdf.map import DenseGrid, TsdfMap


@dataclass
class Mesh:
    vertices: np.ndarray
    """(V, 3) float32 world positions, m."""
    faces: np.ndarray
    """(F, 3) int64 vertex indices, counter-clockwise seen from the free side."""
    colors: np.ndarray
    """(V, 3) uint8 vertex colours."""

    @staticmethod
    def concat(meshes: list[Mesh]) -> Mesh:
        if not meshes:
            return Mesh(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64), np.zeros((0, 3), np.uint8))
        offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
        return Mesh(np.concatenate([m.vertices for m in meshes]),
                    np.concatenate([m.faces + o for m, o in zip(meshes, offsets)]),
                    np.concatenate([m.colors for m in meshes]))


def _corner_observed(weight: np.ndarray, min_weight: float) -> np.ndarray:
    """(X, Y, Z) bool in scikit-image's mask layout, where element i stands for the cube with corners
    i - 1 .. i: True where all 8 corners are observed."""
    ok = weight >= min_weight
    out = ok.copy()
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                shifted = np.zeros_like(ok)
                shifted[dx:, dy:, dz:] = ok[:ok.shape[0] - dx, :ok.shape[1] - dy, :ok.shape[2] - dz]
                out &= shifted
    return out


def marching_cubes(tsdf: np.ndarray, weight: np.ndarray, color: np.ndarray, origin_centre_m: np.ndarray,
                   voxel_size_m: float, min_weight: float = 1.0) -> Mesh:
    """Zero level set of a dense (X, Y, Z) tsdf grid whose voxel [0, 0, 0] is centred at
    ``origin_centre_m``; only cubes with 8 observed corners make triangles."""
    from skimage.measure import marching_cubes as skimage_mc  # perception extra

    mask = _corner_observed(weight, min_weight)
    if not mask.any() or tsdf[weight >= min_weight].min() >= 0 or tsdf[weight >= min_weight].max() <= 0:
        return Mesh.concat([])
    try:
        verts, faces, _, _ = skimage_mc(tsdf, level=0.0, mask=mask, allow_degenerate=False)
    except (ValueError, RuntimeError):  # no crossing inside the mask
        return Mesh.concat([])
    idx = np.clip(np.round(verts).astype(np.int64), 0, np.array(tsdf.shape) - 1)
    colors = color[idx[:, 0], idx[:, 1], idx[:, 2]]
    # skimage orders triangles for increasing values outward; tsdf grows into free space, so flip
    return Mesh((verts * voxel_size_m + origin_centre_m).astype(np.float32), faces[:, ::-1].astype(np.int64),
                colors.astype(np.uint8))


def extract_mesh(grid: DenseGrid, min_weight: float = 1.0) -> Mesh:
    """The whole map's mesh from a dense grid (``TsdfMap.dense()``)."""
    origin = grid.origin_m.cpu().numpy()
    return marching_cubes(grid.tsdf.cpu().numpy(), grid.weight.cpu().numpy(), grid.color.cpu().numpy(), origin,
                          grid.voxel_size_m, min_weight)


class IncrementalMesher:
    """Keeps one mesh per block and re-meshes only blocks changed since the last ``update``.

    Block b owns the cubes whose lowest corner is one of its voxels, so it reads a
    (B + 1)^3 grid: its voxels plus the first layer of its +x/+y/+z neighbours.
    """

    def __init__(self, tsdf_map: TsdfMap, min_weight: float = 1.0):
        self.map, self.min_weight = tsdf_map, min_weight
        self.blocks: dict[int, Mesh] = {}

    def _padded(self, slots: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        m, b = self.map, self.map.cfg.block_voxels
        coords = m.hash.slot_coords[slots]
        idx = torch.arange(b + 1, device=m.device)
        local = torch.stack(torch.meshgrid(idx, idx, idx, indexing="ij"), -1).reshape(-1, 3)  # ((B+1)^3, 3)
        voxel = coords[:, None, :] * b + local[None]
        owner = torch.div(voxel, b, rounding_mode="floor")
        within = voxel - owner * b
        owner_slot = m.hash.find(owner.reshape(-1, 3)).reshape(owner.shape[:2])
        flat = (within[..., 0] * b + within[..., 1]) * b + within[..., 2]
        have = owner_slot >= 0
        s = owner_slot.clamp(min=0)
        tsdf = torch.where(have, m.tsdf[s, flat], torch.ones_like(flat, dtype=torch.float32))
        weight = torch.where(have, m.weight[s, flat], torch.zeros_like(flat, dtype=torch.float32))
        color = m.color[s, flat]
        shape = (len(slots), b + 1, b + 1, b + 1)
        return tsdf.reshape(shape), weight.reshape(shape), color.reshape(*shape, 3)

    def update(self) -> Mesh:
        """Re-mesh the changed blocks and return the whole mesh."""
        slots = self.map.clear_updated()
        if len(slots):
            b, vs = self.map.cfg.block_voxels, self.map.cfg.voxel_size_m
            tsdf, weight, color = (t.cpu().numpy() for t in self._padded(slots))
            origins = (self.map.hash.slot_coords[slots] * b).to(torch.float64).cpu().numpy() * vs
            for i, slot in enumerate(slots.tolist()):
                self.blocks[slot] = marching_cubes(tsdf[i], weight[i], color[i], origins[i], vs, self.min_weight)
        return self.mesh()

    def mesh(self) -> Mesh:
        return Mesh.concat([m for m in self.blocks.values() if len(m.faces)])


def write_ply(path: str | Path, mesh: Mesh) -> Path:
    """Write ``mesh`` as a binary little-endian PLY with vertex colours (MeshLab, Open3D, Blender read it)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    header = ("ply\nformat binary_little_endian 1.0\n"
              f"element vertex {len(mesh.vertices)}\nproperty float x\nproperty float y\nproperty float z\n"
              "property uchar red\nproperty uchar green\nproperty uchar blue\n"
              f"element face {len(mesh.faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    vertex = np.zeros(len(mesh.vertices), dtype=[("p", "<f4", 3), ("c", "u1", 3)])
    vertex["p"], vertex["c"] = mesh.vertices, mesh.colors
    face = np.zeros(len(mesh.faces), dtype=[("n", "u1"), ("i", "<i4", 3)])
    face["n"], face["i"] = 3, mesh.faces
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(vertex.tobytes())
        f.write(face.tobytes())
    return path


__all__ = ["IncrementalMesher", "Mesh", "extract_mesh", "marching_cubes", "write_ply"]
