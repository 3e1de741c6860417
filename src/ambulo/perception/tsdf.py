"""TSDF integration with colour into sparse voxel blocks (nvblox / Open3D ``VoxelBlockGrid``).

Projective TSDF (Curless & Levoy 1996; as in KinectFusion, voxblox, nvblox, Open3D): a voxel at
camera depth z whose centre projects to a pixel of depth d has signed distance sdf = d - z,
truncated to ``trunc = truncation_voxels * voxel_size_m`` and stored as tsdf = min(sdf, trunc) /
trunc in [-1, 1], averaged over frames with weight 1 per observation; voxels further than
``trunc`` behind the surface (sdf < -trunc) are not touched. Blocks are allocated around every
observed surface point; allocated blocks in the view that hold a surface are updated too, which
is what clears space once seen occupied.

Dynamic obstacles: a voxel that holds a surface (tsdf < 0) but is now seen at least ``trunc`` in
front of the measured depth is *free*, so its history is dropped (weight reset) before the
update: a box that moved away is gone from the map in the first frame that sees the space it left
(nvblox does the same with a separate freespace layer; voxblox users wait ~2 s: voxblox#263).
"""

from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
import torch

from ambulo.utils.checks import check_int, check_positive

from . import tsdf_kernels
from .block_hash import BlockHash, decode, encode, raise_out_of_range
from .frames import RgbdFrame, pixel_rays


@dataclass(kw_only=True)
class TsdfCfg:
    """Resolution, truncation and limits of a ``TsdfMap``."""

    voxel_size_m: float = 0.05
    """Voxel edge, m (nvblox's and this issue's 5 cm)."""
    block_voxels: int = 8
    """Voxels per block edge (8^3 per block, as nvblox and Open3D)."""
    truncation_voxels: float = 4.0
    """Truncation distance in voxels (nvblox's default 4)."""
    max_weight: float = 64.0
    """Weights saturate here, so the map keeps adapting (voxblox's ``max_weight``)."""
    depth_min_m: float = 0.1
    depth_max_m: float = 5.0
    """Depth readings outside [min, max] are ignored, m."""
    allocation_stride: int = 4
    """Blocks are allocated from every n-th pixel in each direction (a block spans tens of pixels)."""
    weight_ref_depth_m: float | None = None
    """Observations beyond this depth weigh (ref / z)^2 instead of 1 (the inverse-square weighting of
    voxblox and nvblox: a structured-light / stereo depth error grows as z^2, so its variance as z^4;
    the square keeps far readings useful). None weighs every reading 1, as Open3D does."""
    clear_free_space: bool = True
    """Drop the history of a surface voxel seen ``trunc`` in front of the measured depth."""

    def __post_init__(self):
        check_positive("voxel_size_m", self.voxel_size_m, "pass metres > 0, e.g. 0.05")
        check_int("block_voxels", self.block_voxels, "pass a whole number of voxels, e.g. 8", minimum=2)
        check_positive("truncation_voxels", self.truncation_voxels, "pass voxels > 0, e.g. 4")
        check_int("allocation_stride", self.allocation_stride, "pass a pixel stride >= 1", minimum=1)

    @property
    def truncation_m(self) -> float:
        return self.truncation_voxels * self.voxel_size_m

    @property
    def block_size_m(self) -> float:
        return self.block_voxels * self.voxel_size_m


def sample_depth(depth: torch.Tensor, u: torch.Tensor, v: torch.Tensor,
                 max_step: float = 0.05) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Depth at sub-pixel positions (u, v): bilinear between the 4 neighbouring pixels where all
    four are valid and within ``max_step`` (relative) of each other, else the nearest pixel (no
    blending across depth edges). Nearest-pixel lookup alone (Open3D) misplaces a grazing floor by
    up to half a pixel's depth change (~5 mm at 3 m). Returns depth (0 = none), the nearest pixel's
    flat index (for colour) and whether (u, v) is in the image."""
    h, w = depth.shape
    in_image = (u > -0.5) & (u < w - 0.5) & (v > -0.5) & (v < h - 0.5)
    ui, vi = torch.round(u).long().clamp_(0, w - 1), torch.round(v).long().clamp_(0, h - 1)
    nearest = vi * w + ui
    flat = depth.reshape(-1)
    d_near = torch.take(flat, nearest)
    u0, v0 = torch.floor(u).long().clamp_(0, w - 2), torch.floor(v).long().clamp_(0, h - 2)
    fu, fv = (u - u0).clamp(0, 1), (v - v0).clamp(0, 1)
    i00 = v0 * w + u0
    d00, d01, d10, d11 = (torch.take(flat, i00 + o) for o in (0, 1, w, w + 1))
    lo = torch.minimum(torch.minimum(d00, d01), torch.minimum(d10, d11))
    hi = torch.maximum(torch.maximum(d00, d01), torch.maximum(d10, d11))
    smooth = (lo > 0) & (hi - lo <= max_step * lo)
    bilinear = (d00 * (1 - fu) + d01 * fu) * (1 - fv) + (d10 * (1 - fu) + d11 * fu) * fv
    d = torch.where(smooth, bilinear, d_near)
    return torch.where(in_image, d, torch.zeros_like(d)), nearest, in_image


_NO_DEPTH = tsdf_kernels.NO_DEPTH
"""Depth of the padded image's border: a voxel projecting off the image reads it and is not updated."""
_MAX_STEP = tsdf_kernels.MAX_STEP
"""Relative depth spread of a 2x2 pixel cell up to which the depth lookup interpolates."""
_MAX_DENSE_CELLS = 1 << 21
"""Largest dense block volume (cells) used to deduplicate a frame's blocks without a sort."""


def _host(t: torch.Tensor) -> np.ndarray:
    """A host tensor's values as numpy without a torch op where it is already a plain CPU tensor."""
    return t.numpy() if t.device.type == "cpu" and not t.requires_grad else t.detach().cpu().numpy()


@contextmanager
def _one_torch_thread(device: torch.device):
    """Run the enclosed CPU torch ops on the calling thread only (no-op on other devices)."""
    if device.type != "cpu":
        yield
        return
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


@dataclass
class _FrameBuffers:
    """Per-image-size working buffers of ``TsdfMap.integrate`` (kept between frames)."""

    shape: tuple[int, int]
    k: np.ndarray
    """(3, 3) float32 intrinsics the buffers were built for."""
    rays: torch.Tensor
    """(H/s, W/s, 3) float32 camera rays (z = 1) of the allocation pixels."""
    depth: torch.Tensor
    """(H + 2, W + 2) float32 depth (non-finite readings as _NO_DEPTH, which fails every depth range
    test as they do), _NO_DEPTH on the 1-pixel border."""
    depth_inner: torch.Tensor
    """(H, W) view of ``depth`` without its border (the frame's depth is copied in here)."""
    rgb: torch.Tensor
    """(H + 2, W + 2, 3) uint8 colour, same padding."""
    band: torch.Tensor
    """(3, 1, 1, 1) float32 offsets -trunc, 0, trunc along a ray, m."""
    r_blocks: int
    volume: torch.Tensor | None
    """(side^3 + 1,) bool dense block cells around the camera (torch path), None where too big."""
    strides: torch.Tensor
    volume_stamp: torch.Tensor | None = None
    """(parts, side^3) int32 frame stamp of each cell, per part of ``mark_band_blocks`` (Warp path: the
    volume is never cleared)."""
    new_keys: torch.Tensor | None = None
    """(parts, side^3) int64 keys of this frame's new blocks, per part (Warp path)."""


@dataclass
class _FrameGeometry:
    """A frame's small per-frame matrices, computed on the host (numpy float32, as the kernels take
    them by value) and shared by both backends, so that both do the same float32 arithmetic."""

    k: np.ndarray
    """(3, 3) float32 intrinsics."""
    rot_cw: np.ndarray
    """(3, 3) float32 world-to-camera rotation; t_cw: (3,) its translation, m."""
    t_cw: np.ndarray
    kr: np.ndarray
    """(3, 3) float32 K' R_cw, K' = K with the principal point shifted by the 1-pixel pad; kt = K' t_cw."""
    kt: np.ndarray
    local_px: np.ndarray
    """(3, B^3) float32 K' R_cw of each local voxel offset."""
    rot_blocks: np.ndarray
    """(3, 3) float32 R_wc^T / block size: ray @ rot_blocks is a ray's world direction in blocks / m."""
    start_blocks: np.ndarray
    """(3,) float32 camera position in blocks + 0.5 / B."""
    position_blocks: np.ndarray
    """(3,) float32 camera position in blocks."""


class TsdfMap:
    """A colour TSDF in blocks of ``block_voxels``^3 voxels, allocated as surfaces are seen.

    Voxel (i, j, k) (world integer index) is centred at (i, j, k) * voxel_size_m (Open3D's
    convention, so both grids sample the same points) and covers [i - 0.5, i + 0.5) voxels. Block b holds voxels ``b * block_voxels + local``;
    within a block, voxels are stored flat as ``(lx * B + ly) * B + lz``.

    ``backend`` picks the allocation and per-voxel update: "warp" (fused Warp kernels, ``tsdf_kernels``;
    CPU and CUDA, same result), "torch" (eager torch ops, the reference) or "auto" (Warp when
    importable, on the CPU too, where it measured faster than torch: see ``tsdf_kernels``).
    """

    def __init__(self, cfg: TsdfCfg | None = None, device: torch.device | str = "cpu", capacity: int = 1024,
                 backend: str = "auto"):
        self.cfg = cfg or TsdfCfg()
        self.device = torch.device(device)
        if backend not in ("auto", "warp", "torch"):
            raise ValueError(f"backend={backend!r}: pass 'auto', 'warp' or 'torch'")
        if backend == "warp" and not tsdf_kernels.available():
            raise ImportError("backend='warp' needs warp-lang: pip install 'ambulo[perception]'")
        if backend == "auto":
            backend = "warp" if tsdf_kernels.available() else "torch"
        self.backend = backend
        """The per-voxel update in use: "warp" or "torch"."""
        self.hash = BlockHash(self.device, capacity)
        b = self.cfg.block_voxels
        n = b ** 3
        self.tsdf = torch.ones((capacity, n), dtype=torch.float32, device=self.device)
        """(capacity, B^3) float32 truncated signed distance / truncation, in [-1, 1]; rows are slots."""
        self.weight = torch.zeros((capacity, n), dtype=torch.float32, device=self.device)
        """(capacity, B^3) float32 integration weight; 0 = never observed."""
        self.color = torch.zeros((capacity, n, 3), dtype=torch.uint8, device=self.device)
        """(capacity, B^3, 3) uint8 weighted mean colour."""
        self.updated = torch.zeros(capacity, dtype=torch.bool, device=self.device)
        """(capacity,) bool: blocks changed since ``clear_updated`` (for incremental meshing)."""
        self.has_surface = torch.zeros(capacity, dtype=torch.bool, device=self.device)
        """(capacity,) bool: blocks holding an observed voxel behind a surface (tsdf < 0)."""
        idx = torch.arange(n, device=self.device)
        self._local = torch.stack([idx // (b * b), (idx // b) % b, idx % b], -1)
        """(B^3, 3) int64 local voxel index of each flat voxel."""
        self._local_index = idx
        """(B^3,) int64 flat local voxel index."""
        self._local_m = (self._local.cpu().numpy().astype(np.float32) * np.float32(self.cfg.voxel_size_m)).T.copy()
        """(3, B^3) float32 (host) local voxel offsets from the block origin, m."""
        self._buf: _FrameBuffers | None = None
        self._stamp = 0
        """Frame counter of the Warp path's stamps (a cell / slot holding this frame's stamp is marked)."""
        if self.backend == "warp":
            self._launches = tsdf_kernels.IntegrateLaunches(self.device, b)
            """The recorded Warp launches and their shared counters."""
            self._slot_stamp = torch.zeros((capacity, self._launches.parts), dtype=torch.int32, device=self.device)
            """(capacity, parts) int32 stamp of the frame whose allocation band last touched each slot, per
            part of ``mark_band_blocks``."""
            self._selected = torch.zeros(capacity, dtype=torch.int64, device=self.device)
            """(capacity,) int64 old slots this frame updates, the first ``counts[0]`` of them."""

    @property
    def num_blocks(self) -> int:
        return len(self.hash)

    def block_coords(self) -> torch.Tensor:
        """(num_blocks, 3) int64 block coordinates by slot."""
        return self.hash.slot_coords

    def voxel_index(self, slots: torch.Tensor | None = None) -> torch.Tensor:
        """(n, B^3, 3) int64 world voxel indices of the voxels of ``slots`` (default all blocks)."""
        coords = self.hash.slot_coords if slots is None else self.hash.slot_coords[slots]
        return coords[:, None, :] * self.cfg.block_voxels + self._local[None]

    def _grow(self, needed: int) -> None:
        capacity = self.tsdf.shape[0]
        if needed <= capacity:
            return
        new = max(needed, 2 * capacity)
        extra = new - capacity
        self.tsdf = torch.cat([self.tsdf, self.tsdf.new_ones((extra, self.tsdf.shape[1]))])
        self.weight = torch.cat([self.weight, self.weight.new_zeros((extra, self.weight.shape[1]))])
        self.color = torch.cat([self.color, self.color.new_zeros((extra, *self.color.shape[1:]))])
        self.updated = torch.cat([self.updated, self.updated.new_zeros(extra)])
        self.has_surface = torch.cat([self.has_surface, self.has_surface.new_zeros(extra)])
        if self.backend == "warp":
            # both are grown between select_blocks and the voxel update: keep the selected slots
            stamps = self._slot_stamp
            self._slot_stamp = torch.cat([stamps, stamps.new_zeros((extra, stamps.shape[1]))])
            self._selected = torch.cat([self._selected, self._selected.new_zeros(extra)])

    def _geometry(self, frame: RgbdFrame) -> _FrameGeometry:
        """The frame's small matrices on the host: no device op, no upload (the kernels take them by value)."""
        pose = _host(frame.pose_wc).astype(np.float64)
        pose_cw = np.linalg.inv(pose).astype(np.float32)
        pose_wc = pose.astype(np.float32)
        k = _host(frame.intrinsics).astype(np.float32)
        kp = k.copy()
        kp[:2, 2] += np.float32(1.0)
        kr = kp @ pose_cw[:3, :3]
        inv = np.float32(1.0 / self.cfg.block_size_m)
        position = pose_wc[:3, 3] * inv
        return _FrameGeometry(k=k, rot_cw=pose_cw[:3, :3].copy(), t_cw=pose_cw[:3, 3].copy(), kr=kr,
                              kt=kp @ pose_cw[:3, 3], local_px=kr @ self._local_m, rot_blocks=pose_wc[:3, :3].T * inv,
                              start_blocks=position + np.float32(0.5 / self.cfg.block_voxels),
                              position_blocks=position)

    def _frame_buffers(self, h: int, w: int, k: np.ndarray) -> _FrameBuffers:
        """Per-image-size buffers, built once: padded depth / colour images and the rays of the
        allocation pixels (rebuilt when the image size or the intrinsics change)."""
        buf = self._buf
        if buf is None or buf.shape != (h, w) or not np.array_equal(buf.k, k):
            s = self.cfg.allocation_stride
            rays = pixel_rays(torch.from_numpy(k), h, w, self.device)[::s, ::s].contiguous()
            r_blocks = int(math.ceil((self.cfg.depth_max_m + self.cfg.truncation_m) * float(rays.norm(dim=-1).max())
                                     / self.cfg.block_size_m)) + 2
            side = 2 * r_blocks + 1
            band_m = torch.tensor([-self.cfg.truncation_m, 0.0, self.cfg.truncation_m], device=self.device)
            depth_pad = torch.full((h + 2, w + 2), _NO_DEPTH, dtype=torch.float32, device=self.device)
            buf = self._buf = _FrameBuffers(
                shape=(h, w), k=k.copy(), rays=rays, depth=depth_pad, depth_inner=depth_pad[1:h + 1, 1:w + 1],
                rgb=torch.zeros((h + 2, w + 2, 3), dtype=torch.uint8, device=self.device),
                band=band_m.view(3, 1, 1, 1), r_blocks=r_blocks,
                volume=torch.zeros(side ** 3 + 1, dtype=torch.bool, device=self.device)
                if side ** 3 <= _MAX_DENSE_CELLS else None,
                strides=torch.tensor([side * side, side, 1], dtype=torch.float32, device=self.device))
            if self.backend == "warp" and buf.volume is not None:
                parts = self._launches.parts
                buf.volume_stamp = torch.zeros((parts, side ** 3), dtype=torch.int32, device=self.device)
                buf.new_keys = torch.zeros((parts, side ** 3), dtype=torch.int64, device=self.device)
        return buf

    def _corner_blocks(self, buf: _FrameBuffers, g: _FrameGeometry) -> np.ndarray:
        """(3,) float32 block coordinate of cell 0 of the dense volume around the camera."""
        return np.floor(g.position_blocks) - np.float32(buf.r_blocks)

    def _allocate(self, depth: torch.Tensor, buf: _FrameBuffers, g: _FrameGeometry) -> torch.Tensor:
        """Allocate the blocks that the truncation band of every ``allocation_stride``-th valid pixel
        touches; return their slots. Deduplicated sort-free, through a dense volume of block cells
        around the camera (``torch.unique`` only when the depth range makes that volume too big)."""
        s = self.cfg.allocation_stride
        # the band [d - trunc, d + trunc] along each ray: a block (>= 2 trunc here) is hit by one of 3
        # samples; block = floor(round(p / voxel) / B) = floor(p / block + 0.5 / B), in block units. Products
        # and sums one op each (no fused multiply-add), as the Warp kernel computes them
        m = torch.from_numpy(g.rot_blocks).to(self.device)
        rays_w = buf.rays[..., 0:1] * m[0] + buf.rays[..., 1:2] * m[1] + buf.rays[..., 2:3] * m[2]
        start = torch.from_numpy(g.start_blocks).to(self.device)
        d = depth[::s, ::s]
        valid = (d >= self.cfg.depth_min_m) & (d <= self.cfg.depth_max_m)  # False for NaN and inf too
        samples = torch.mul(rays_w, d[..., None] + buf.band).add_(start).floor_()
        if buf.volume is not None:
            side = 2 * buf.r_blocks + 1
            corner = torch.from_numpy(self._corner_blocks(buf, g)).to(self.device)
            cell = (samples - corner).clamp_(0, side - 1) @ buf.strides
            cell = torch.where(valid.expand(3, -1, -1), cell, side ** 3).to(torch.int64).reshape(-1)
            vol = buf.volume
            vol.zero_()
            vol.index_fill_(0, cell, True)
            vol[-1] = False
            flat = torch.nonzero(vol, as_tuple=True)[0]
            coords = torch.stack([flat // (side * side), (flat // side) % side, flat % side], -1) + corner.to(torch.int64)
        else:
            coords = decode(torch.unique(encode(samples[valid.expand(3, -1, -1)].to(torch.int64))))
        slots = self.hash.insert(coords)
        self._grow(len(self.hash))
        return slots

    def _blocks_in_view(self, depth: torch.Tensor, g: _FrameGeometry) -> torch.Tensor:
        """Slots of allocated blocks holding a surface that intersect the view and are not wholly
        behind the measured depth: the blocks where a moved obstacle may have to be cleared (the Warp
        path's ``select_blocks``, the same float32 operations)."""
        size = self.cfg.block_size_m
        cand = torch.nonzero(self.has_surface[: self.num_blocks], as_tuple=True)[0]
        centres = (self.hash.slot_coords[cand].to(torch.float32) + 0.5) * size - 0.5 * self.cfg.voxel_size_m
        rot, t = torch.from_numpy(g.rot_cw).to(self.device), torch.from_numpy(g.t_cw).to(self.device)
        cx, cy, cz = centres.unbind(1)
        x, y, z = (cx * rot[a, 0] + cy * rot[a, 1] + cz * rot[a, 2] + t[a] for a in range(3))
        radius, radius_px = self._block_radius(g)
        h, w = depth.shape
        zc = z.clamp(min=1e-3)
        k = g.k
        u = torch.round(x / zc * float(k[0, 0]) + float(k[0, 2])).long()
        v = torch.round(y / zc * float(k[1, 1]) + float(k[1, 2])).long()
        margin_px = zc.reciprocal().mul_(radius_px).long()
        near = (z + radius > self.cfg.depth_min_m) & (z - radius < self.cfg.depth_max_m)
        inside = (u + margin_px >= 0) & (u - margin_px < w) & (v + margin_px >= 0) & (v - margin_px < h)
        # keep blocks in front of (or in the band of) the surface seen near their centre; a block whose
        # centre pixel is off-image or empty is kept (cheap, and its voxels are checked one by one)
        d = depth[v.clamp(0, h - 1), u.clamp(0, w - 1)]
        valid = (d >= self.cfg.depth_min_m) & (d <= self.cfg.depth_max_m)
        keep = near & inside & (z > 0) & (~valid | (z - radius < d + self.cfg.truncation_m))
        return cand[keep]

    def _block_radius(self, g: _FrameGeometry) -> tuple[float, float]:
        """Half a block's diagonal, m, and that times fx (float32 values, so torch and Warp agree)."""
        radius = np.float32(0.87 * self.cfg.block_size_m)
        return float(radius), float(radius * g.k[0, 0])

    def integrate(self, frame: RgbdFrame) -> None:
        """Fuse one frame (depth, optional colour, ``pose_wc``) into the map."""
        if frame.pose_wc is None:
            raise ValueError("TsdfMap.integrate needs frame.pose_wc (camera-to-world, OpenCV axes)")
        depth = frame.depth_m.to(self.device, torch.float32)
        h, w = depth.shape
        g = self._geometry(frame)
        buf = self._frame_buffers(h, w, g.k)
        rgb = None if frame.rgb is None else frame.rgb.to(self.device)
        if self.backend == "warp":
            self._integrate_warp(depth, rgb, buf, g)
            return
        # padded copy with a 1-pixel _NO_DEPTH border, so a voxel projecting off the image reads a
        # depth far in front of it: no separate in-image test. Depth validity is checked per voxel, on
        # the few that are looked up, not on every pixel
        torch.nan_to_num(depth, nan=_NO_DEPTH, posinf=_NO_DEPTH, neginf=_NO_DEPTH, out=buf.depth_inner)
        if rgb is not None:
            buf.rgb[1:h + 1, 1:w + 1] = rgb
        new_slots = self._allocate(depth, buf, g)
        mask = torch.zeros(self.num_blocks, dtype=torch.bool, device=self.device)
        mask[new_slots] = True
        mask[self._blocks_in_view(depth, g)] = True
        slots = torch.nonzero(mask, as_tuple=True)[0]
        self._update_voxels_torch(slots, buf, g, rgb is not None)

    def _integrate_warp(self, depth: torch.Tensor, rgb: torch.Tensor | None, buf: _FrameBuffers,
                        g: _FrameGeometry) -> None:
        """``integrate`` in recorded Warp launches: pad the frame, mark the band's blocks (looking them up
        in the hash), select the old blocks to update, then one host read of the counters (new keys,
        selected blocks) to allocate the new blocks, and update the voxels of the selected and the new
        blocks. Torch ops per frame: the padded depth copy, on CUDA the counters' reset and read and the
        local offsets' upload (none of those three on the CPU: numpy views), and when blocks are added
        none more on the CPU, 8 small ones on CUDA (the hash's in-place merge: its buffers stay the tensors
        the launches bind); the per-frame matrices go to the kernels by value."""
        cfg, launches = self.cfg, self._launches
        self._stamp += 1
        stamp, num_old = self._stamp, self.num_blocks
        launches.reset_counts()
        # the padded depth copy in one torch op (0.03 ms; a Warp kernel took ~1 ms: Warp's CPU code does not
        # vectorise), on one torch thread: a parallel region leaves torch's OpenMP threads spinning for ms
        # on the cores the voxel launches then need (on 2 cores the update took 2.8 ms instead of 2.0).
        # The kernels read only this copy, so the frame's depth tensor is never handed to Warp
        with _one_torch_thread(depth.device):
            torch.nan_to_num(depth, nan=_NO_DEPTH, posinf=_NO_DEPTH, neginf=_NO_DEPTH, out=buf.depth_inner)
        if buf.volume is not None:
            corner = self._corner_blocks(buf, g)
            launches.mark(
                depth_pad_m=buf.depth, stride_px=cfg.allocation_stride, rays=buf.rays, rot_blocks=g.rot_blocks,
                start_blocks=g.start_blocks, band_m=(-cfg.truncation_m, 0.0, cfg.truncation_m),
                corner_blocks=corner, corner_index=corner.astype(np.int64), side=2 * buf.r_blocks + 1,
                depth_min_m=cfg.depth_min_m, depth_max_m=cfg.depth_max_m, stamp=stamp,
                volume_stamp=buf.volume_stamp, keys=self.hash.key_buffer, key_slots=self.hash.key_slot_buffer,
                num_keys=num_old, slot_stamp=self._slot_stamp, new_keys=buf.new_keys)
        else:  # the depth range is too deep for a dense volume: the torch path's sort-based allocation
            slots = self._allocate(depth, buf, g)  # may grow the storage, _slot_stamp included
            self._slot_stamp[slots, 0] = stamp
        radius, radius_px = self._block_radius(g)
        k = g.k
        launches.select(
            num_old=num_old, stamp=stamp, slot_stamp=self._slot_stamp, slot_coords=self.hash.slot_coord_buffer,
            rot_cw=g.rot_cw, t_cw=g.t_cw, k4=(k[0, 0], k[1, 1], k[0, 2], k[1, 2]),
            centre_scale=(0.5, cfg.block_size_m, 0.5 * cfg.voxel_size_m), radius_m=radius, radius_px_m=radius_px,
            truncation_m=cfg.truncation_m, depth_min_m=cfg.depth_min_m, depth_max_m=cfg.depth_max_m,
            depth_pad_m=buf.depth, has_surface=self.has_surface, selected=self._selected)
        launches.set_local_px(g.local_px)
        counts = launches.read_counts()  # the one host read (on CUDA it waits for the kernels so far)
        n_selected = counts[0]
        if buf.volume is not None:
            if any(counts[2::2]):
                raise_out_of_range()
            new = [buf.new_keys[p, :n] for p, n in enumerate(counts[1::2]) if n]
            if new:
                # each part's keys are distinct; a block new to two parts is in both lists
                if len(new) == 1:
                    self.hash.append(new[0], presorted=False)  # slots num_old, num_old + 1, ... in key order
                else:
                    self.hash.append(torch.unique(torch.cat(new)))
                self._grow(self.num_blocks)
        launches.update_voxels(
            num_blocks=n_selected + self.num_blocks - num_old, selected=self._selected, num_selected=n_selected,
            first_new_slot=num_old, slot_coords=self.hash.slot_coord_buffer, block_voxels=cfg.block_voxels,
            voxel_size_m=cfg.voxel_size_m, kr=g.kr, kt=g.kt, depth_pad_m=buf.depth, rgb=rgb,
            truncation_m=cfg.truncation_m, depth_min_m=cfg.depth_min_m, depth_max_m=cfg.depth_max_m,
            max_weight=cfg.max_weight, weight_ref_depth_m=cfg.weight_ref_depth_m, clear_free_space=cfg.clear_free_space,
            tsdf=self.tsdf, weight=self.weight, color=self.color, updated=self.updated, has_surface=self.has_surface)

    def _project(self, slots: torch.Tensor, g: _FrameGeometry) -> tuple[torch.Tensor, torch.Tensor]:
        """Homogeneous padded-pixel coordinates (K' [R | t] p) of every voxel centre as block origin +
        local offset: (3, n) of the blocks' origins and (3, B^3) of the local offsets, summed per voxel
        (one add instead of a product per voxel). The origins' products and sums one op each, as the
        Warp kernel computes them."""
        kr, kt = torch.from_numpy(g.kr).to(self.device), torch.from_numpy(g.kt).to(self.device)
        origin = (self.hash.slot_coords[slots] * self.cfg.block_voxels).to(torch.float32) * self.cfg.voxel_size_m
        ox, oy, oz = origin.unbind(1)
        origin_px = torch.stack([ox * kr[a, 0] + oy * kr[a, 1] + oz * kr[a, 2] + kt[a] for a in range(3)])
        return origin_px, torch.from_numpy(g.local_px).to(self.device)

    def _update_voxels_torch(self, slots: torch.Tensor, buf: _FrameBuffers, g: _FrameGeometry,
                             with_color: bool) -> None:
        """The per-voxel update in eager torch ops (the reference of the Warp kernel ``integrate_voxels``)."""
        cfg = self.cfg
        h, w = buf.shape
        wp = w + 2
        origin_px, local_px = self._project(slots, g)
        p = origin_px[:, :, None] + local_px[:, None, :]
        x, y, z = p.view(3, -1)
        zc = z.clamp(min=1e-6)
        trunc = cfg.truncation_m
        # sub-pixel position in the padded image (written over x, y), clamped so the 2x2 cell stays
        # inside it; anything off the image lands on the _NO_DEPTH border
        u = x.div_(zc).clamp_(0.0, w + 0.75)
        v = y.div_(zc).clamp_(0.0, h + 0.75)
        flat = buf.depth.view(-1)
        # 1. the nearest pixel's depth bounds the interpolated one: the 4 pixels are interpolated only
        # when within _MAX_STEP of each other (then |bilinear - nearest| <= _MAX_STEP * nearest), so a
        # voxel with (1 + _MAX_STEP) * nearest - z < -trunc can not be updated; keep only the others
        d_near = torch.take(flat, v.round().mul_(wp).add_(u.round()).to(torch.int64))
        cand = d_near.mul_(1.0 + _MAX_STEP) >= z - trunc
        sel = torch.nonzero(cand, as_tuple=True)[0]
        u, v, z = x.take(sel), y.take(sel), z.take(sel)
        # 2. the candidates: bilinear depth where the cell's 4 pixels are valid and within _MAX_STEP of
        # each other, else the nearest pixel (no blending across depth edges)
        u0, v0 = u.floor(), v.floor()
        fu, fv = u.sub_(u0), v.sub_(v0)
        i00 = v0.mul_(wp).add_(u0)
        near = fv.round().mul_(wp).add_(fu.round()).add_(i00).to(torch.int64)
        idx = i00.to(torch.int64)
        d00, d01 = torch.take(flat, idx), torch.take(flat[1:], idx)
        d10, d11 = torch.take(flat[wp:], idx), torch.take(flat[wp + 1:], idx)
        lo = torch.minimum(torch.minimum(d00, d01), torch.minimum(d10, d11))
        hi = torch.maximum(torch.maximum(d00, d01), torch.maximum(d10, d11))
        smooth = (hi <= lo * (1.0 + _MAX_STEP)) & (lo >= cfg.depth_min_m) & (hi <= cfg.depth_max_m)
        top = torch.addcmul(d00, fu, d01.sub_(d00))
        d = torch.addcmul(top, fv, torch.addcmul(d10, fu, d11.sub_(d10)).sub_(top))
        d = torch.where(smooth, d, torch.take(flat, near))
        sdf = d - z
        update = (sdf >= -trunc) & (d >= cfg.depth_min_m) & (d <= cfg.depth_max_m) & (z > 0)
        tsdf_new = (sdf * (1.0 / trunc)).clamp_(max=1.0)
        # 3. the update, gathered and scattered at the candidates' flat storage indices
        n, nv = slots.numel(), self._local_m.shape[1]
        vox = (slots[:, None] * nv + self._local_index).view(-1).take(sel)
        flat_t, flat_w = self.tsdf.view(-1), self.weight.view(-1)
        old_t, old_w = flat_t.take(vox), flat_w.take(vox)
        if cfg.clear_free_space:
            old_w.masked_fill_(update & (sdf >= trunc) & (old_t < 0), 0.0)
        if cfg.weight_ref_depth_m is None:
            w_obs = update.to(torch.float32)
        else:
            w_obs = torch.where(update, (cfg.weight_ref_depth_m / z.clamp(min=1e-6)).square_().clamp_(max=1.0), 0.0)
        total = old_w.add_(w_obs)
        blend = w_obs.div_(total + 1e-12)
        flat_t.index_copy_(0, vox, torch.addcmul(old_t, blend, tsdf_new.sub_(old_t)))
        flat_w.index_copy_(0, vox, total.clamp_(max=cfg.max_weight))
        if with_color:
            # (M, 3) rows, blend expanded to the same contiguous shape (a broadcast over an inner
            # dimension of 3 is far slower on the CPU)
            colours = buf.rgb.view(-1, 3).index_select(0, near).to(torch.float32)
            flat_c = self.color.view(-1, 3)
            old_c = flat_c.index_select(0, vox).to(torch.float32)
            blend3 = blend[:, None].expand(-1, 3).contiguous()
            flat_c.index_copy_(0, vox, torch.addcmul(old_c, blend3, colours.sub_(old_c)).round_().to(torch.uint8))
        touched = torch.zeros(n * nv, dtype=torch.bool, device=self.device).index_copy_(0, sel, update)
        self.updated[slots] |= touched.view(n, nv).any(dim=1)
        # tsdf < 0 only ever with weight > 0
        self.has_surface[slots] = (self.tsdf.index_select(0, slots) < 0).any(dim=1)

    def clear_updated(self) -> torch.Tensor:
        """Slots of the blocks changed since the last call (and forget them)."""
        slots = torch.nonzero(self.updated[: self.num_blocks], as_tuple=True)[0]
        self.updated.zero_()
        return slots

    def dense(self, pad_voxels: int = 0) -> DenseGrid:
        """The allocated blocks' bounding box as dense (X, Y, Z) arrays; unallocated voxels are
        unobserved (weight 0, tsdf 1). Padding adds unobserved voxels around it."""
        b = self.cfg.block_voxels
        coords = self.hash.slot_coords
        if len(coords) == 0:
            raise ValueError("the map is empty: integrate frames before reading it")
        lo = coords.min(0).values * b - pad_voxels
        hi = (coords.max(0).values + 1) * b + pad_voxels
        shape = tuple(int(s) for s in (hi - lo))
        tsdf = torch.ones(shape, dtype=torch.float32, device=self.device)
        weight = torch.zeros(shape, dtype=torch.float32, device=self.device)
        color = torch.zeros((*shape, 3), dtype=torch.uint8, device=self.device)
        idx = (self.voxel_index() - lo).reshape(-1, 3)
        n = self.num_blocks
        tsdf[idx[:, 0], idx[:, 1], idx[:, 2]] = self.tsdf[:n].reshape(-1)
        weight[idx[:, 0], idx[:, 1], idx[:, 2]] = self.weight[:n].reshape(-1)
        color[idx[:, 0], idx[:, 1], idx[:, 2]] = self.color[:n].reshape(-1, 3)
        return DenseGrid(tsdf=tsdf, weight=weight, color=color, origin_index=lo, voxel_size_m=self.cfg.voxel_size_m,
                         truncation_m=self.cfg.truncation_m)

    def memory_bytes(self) -> int:
        """Bytes held by the voxel storage (allocated capacity)."""
        return sum(t.numel() * t.element_size() for t in (self.tsdf, self.weight, self.color))


@dataclass
class DenseGrid:
    """A dense box of a ``TsdfMap``: what ESDF, slices and meshing read."""

    tsdf: torch.Tensor
    """(X, Y, Z) float32 tsdf / truncation in [-1, 1]; 1 where unobserved."""
    weight: torch.Tensor
    """(X, Y, Z) float32 integration weight; 0 = unobserved."""
    color: torch.Tensor
    """(X, Y, Z, 3) uint8 colour."""
    origin_index: torch.Tensor
    """(3,) int64 world voxel index of element [0, 0, 0]."""
    voxel_size_m: float
    truncation_m: float

    @property
    def origin_m(self) -> torch.Tensor:
        """(3,) float64 world position of the *centre* of voxel [0, 0, 0], m."""
        return self.origin_index.to(torch.float64) * self.voxel_size_m

    def centres_m(self) -> torch.Tensor:
        """(X, Y, Z, 3) float64 world voxel centres, m."""
        axes = [torch.arange(n, dtype=torch.float64, device=self.tsdf.device) * self.voxel_size_m
                for n in self.tsdf.shape]
        grid = torch.stack(torch.meshgrid(*axes, indexing="ij"), -1)
        return grid + self.origin_m.to(grid.device)

    def observed(self, min_weight: float = 1.0) -> torch.Tensor:
        return self.weight >= min_weight

    def occupied(self, min_weight: float = 1.0) -> torch.Tensor:
        """(X, Y, Z) bool: observed voxels whose centre lies behind a surface (tsdf < 0)."""
        return self.observed(min_weight) & (self.tsdf < 0)


__all__ = ["DenseGrid", "TsdfCfg", "TsdfMap", "sample_depth"]
