"""TSDF integration with colour into sparse voxel blocks (nvblox / Open3D ``VoxelBlockGrid``).

Projective TSDF (Curless & Levoy 1996; as in KinectFusion, voxblox, nvblox, Open3D): a voxel at
camera depth z whose centre projects to a pixel of depth d has signed distance sdf = d - z,
truncated to ``trunc = truncation_voxels * voxel_size_m`` and stored as tsdf = min(sdf, trunc) /
trunc in [-1, 1], averaged over frames with weight 1 per observation; voxels further than
``trunc`` behind the surface (sdf < -trunc) are not touched, and an observation more than a voxel
behind the surface weighs less, down to 0 at -trunc (voxblox's weight drop-off: through a 10 cm wall
the views from one side otherwise outvote those that see its far side free, and the wall grows).
Blocks are allocated around every observed surface point and, along every ``free_space_stride``-th
allocation ray, in front of it from the camera on (nvblox allocates the blocks a ray crosses too), so
the space seen in front of a surface is *observed free* (tsdf 1), not unknown: a cell the robot
walked through reads free. Memory follows the volume seen within ``depth_max_m`` (a 10 x 8 m flat:
~3k blocks, ~17 MB), not the path. Allocated blocks in the view that hold a surface are updated too,
which is what clears space once seen occupied.

Dynamic obstacles: a voxel that holds a surface (tsdf < 0) but is now seen at least ``trunc`` in
front of the measured depth is *free*, so its history is dropped (weight reset) before the
update: a box that moved away is gone from the map in the first frame that sees the space it left
(nvblox does the same with a separate freespace layer; voxblox users wait ~2 s: voxblox#263).

Modules: this one holds the configuration, the map (storage, hash, ``dense``, ``integrate`` and its Warp
path) and ``DenseGrid``; ``tsdf.reference`` the eager-torch path (a base class of ``TsdfMap``);
``tsdf.frame`` the per-frame buffers both paths share; ``tsdf.kernels`` the Warp kernels and
``tsdf.launches`` their recorded launches.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from ambulo.utils.checks import check_int, check_positive
from ambulo.utils.validate import Checked

from ..frames import RgbdFrame, pixel_rays
from ..torch_threads import one_torch_thread
from . import kernels
from .block_hash import BlockHash, raise_out_of_range
from .frame import _NO_DEPTH, _FrameBuffers, _FrameGeometry
from .graph import SKIP_FULL, IntegrateGraph, check_state
from .kernels import S_NUM_BLOCKS, S_PARTS, S_SELECTED, S_STAMP
from .launches import IntegrateLaunches, voxel_values
from .reference import _TorchIntegration


@dataclass(kw_only=True)
class TsdfCfg(Checked):
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
    free_space_stride: int | None = 4
    """Carve free space: every this many allocation pixels (in each direction) the ray from the camera
    to the surface allocates and updates the blocks it crosses (sampled every ``free_space_step_m``), so
    the space seen in front of surfaces is *observed free*, not unknown (nvblox allocates along rays
    too). None: blocks only around surfaces. The default 4 (every 16th pixel with
    ``allocation_stride`` 4) spaces the rays < 0.16 m apart at 5 m for a 525 px focal length: every
    0.4 m block in the view is crossed by several."""
    free_space_step_m: float = 0.1
    """Depth step of the free-space samples along a ray, m (a quarter block: a block is missed only
    where every ray crosses less than this of it)."""
    weight_dropoff: bool = True
    """Behind the surface by more than a voxel, an observation weighs less, linearly down to 0 at the
    truncation (voxblox's weight drop-off): the far side of a thin wall, seen through it from one
    side, no longer outvotes the views that see it free, which made walls a truncation thicker."""

    def __post_init__(self):
        check_positive("voxel_size_m", self.voxel_size_m, "pass metres > 0, e.g. 0.05")
        check_int("block_voxels", self.block_voxels, "pass a whole number of voxels, e.g. 8", minimum=2)
        check_positive("truncation_voxels", self.truncation_voxels, "pass voxels > 0, e.g. 4")
        check_int("allocation_stride", self.allocation_stride, "pass a pixel stride >= 1", minimum=1)
        if self.free_space_stride is not None:
            check_int("free_space_stride", self.free_space_stride, "pass allocation pixels >= 1, or None", minimum=1)
        check_positive("free_space_step_m", self.free_space_step_m, "pass metres > 0, e.g. 0.1")
        super().__post_init__()

    @property
    def carve_stride(self) -> int:
        """``free_space_stride`` as the kernels take it: 0 for no carving."""
        return 0 if self.free_space_stride is None else self.free_space_stride

    @property
    def dropoff_m(self) -> float:
        """Depth behind the surface from which observations weigh less (``weight_dropoff``), m; 0: off."""
        return self.voxel_size_m if self.weight_dropoff else 0.0

    @property
    def truncation_m(self) -> float:
        return self.truncation_voxels * self.voxel_size_m

    @property
    def block_size_m(self) -> float:
        return self.block_voxels * self.voxel_size_m


_MAX_DENSE_CELLS = 1 << 21
"""Largest dense block volume (cells) used to deduplicate a frame's blocks without a sort."""


def _host(t: torch.Tensor) -> np.ndarray:
    """A host tensor's values as numpy without a torch op where it is already a plain CPU tensor."""
    return t.numpy() if t.device.type == "cpu" and not t.requires_grad else t.detach().cpu().numpy()


class TsdfMap(_TorchIntegration):
    """A colour TSDF in blocks of ``block_voxels``^3 voxels, allocated as surfaces are seen.

    Voxel (i, j, k) (world integer index) is centred at (i, j, k) * voxel_size_m (Open3D's
    convention, so both grids sample the same points) and covers [i - 0.5, i + 0.5) voxels. Block b holds voxels ``b * block_voxels + local``;
    within a block, voxels are stored flat as ``(lx * B + ly) * B + lz``.

    ``backend`` picks the allocation and per-voxel update: "warp" (fused Warp kernels, ``tsdf.kernels``;
    CPU and CUDA, same result), "torch" (eager torch ops, the reference: ``tsdf.reference``) or "auto" (Warp when
    importable, on the CPU too, where it measured faster than torch: see ``tsdf.kernels``). With Warp on
    CUDA a frame is one captured graph (``tsdf.graph``); ``graph=True`` does that on the CPU too (a replay
    there runs on one thread: for tests, slower than the default).
    """

    def __init__(self, cfg: TsdfCfg | None = None, device: torch.device | str = "cpu", capacity: int = 1024,
                 backend: str = "auto", graph: bool = False):
        self.cfg = cfg or TsdfCfg()
        self.device = torch.device(device)
        if backend not in ("auto", "warp", "torch"):
            raise ValueError(f"backend={backend!r}: pass 'auto', 'warp' or 'torch'")
        if backend == "warp" and not kernels.available():
            raise ImportError("backend='warp' needs warp-lang: pip install 'ambulo[perception]'")
        if backend == "auto":
            backend = "warp" if kernels.available() else "torch"
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
            self._launches = IntegrateLaunches(self.device, b)
            """The recorded Warp launches and their shared counters."""
            self._slot_stamp = torch.zeros((capacity, self._launches.parts), dtype=torch.int32, device=self.device)
            """(capacity, parts) int32 stamp of the frame whose allocation band last touched each slot, per
            part of ``mark_band_blocks``."""
            self._selected = torch.zeros(capacity, dtype=torch.int64, device=self.device)
            """(capacity,) int64 old slots this frame updates, the first ``state[S_SELECTED]`` of them."""
            self._view_stamp = torch.zeros(capacity, dtype=torch.int32, device=self.device)
            """(capacity,) int32 stamp of the frame that selected each slot as a surface block in view
            (the CPU's overlapped frame: ``launches.IntegrateLaunches.overlapped``)."""
            self._graph = IntegrateGraph(self._launches) if self._launches.is_cuda or graph else None
            """The frame as one captured graph (CUDA; on the CPU only when asked: ``graph``), else None."""
            self._state_synced = False
            """Whether ``state[S_NUM_BLOCKS]`` holds the block count (the graph keeps it; the eager path not)."""

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
            self._view_stamp = torch.cat([self._view_stamp, self._view_stamp.new_zeros(extra)])

    def _geometry(self, frame: RgbdFrame) -> _FrameGeometry:
        """The frame's small matrices on the host, no device op (the Warp path writes them to its
        ``FrameParams``; the torch path uploads the few it uses)."""
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

    @property
    def block_radius_m(self) -> float:
        """Half a block's diagonal (rounded up a little), m, a float32 value (torch and Warp agree)."""
        return float(np.float32(0.87 * self.cfg.block_size_m))

    def _block_radius(self, g: _FrameGeometry) -> tuple[float, float]:
        """``block_radius_m`` and that times fx (float32 values, so torch and Warp agree)."""
        radius = np.float32(self.block_radius_m)
        return float(radius), float(radius * g.k[0, 0])

    def _reserve(self, blocks: int) -> None:
        """Storage and hash capacity for ``blocks`` blocks (doubling), the storage at least the hash's (the
        graph path checks its new blocks against the hash's capacity)."""
        if blocks > self.hash.capacity:
            self.hash.reserve(max(blocks, 2 * self.hash.capacity))
        self._grow(self.hash.capacity)

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
        self._integrate_torch(depth, rgb, buf, g)

    def _integrate_warp(self, depth: torch.Tensor, rgb: torch.Tensor | None, buf: _FrameBuffers,
                        g: _FrameGeometry) -> None:
        """``integrate`` with the Warp kernels: as one captured graph (``_integrate_graph``) on CUDA, else
        in recorded launches (``_integrate_eager``)."""
        corner = self._corner_blocks(buf, g) if buf.volume is not None else np.zeros(3, np.float32)
        _, radius_px = self._block_radius(g)
        self._launches.set_frame(g, corner, radius_px, rgb is not None)
        # the padded depth copy in one torch op (0.03 ms; a Warp kernel took ~1 ms: Warp's CPU code does not
        # vectorise), on one torch thread: a parallel region leaves torch's OpenMP threads spinning for ms
        # on the cores the voxel launches then need (on 2 cores the update took 2.8 ms instead of 2.0).
        # The kernels read only this copy, so the frame's depth tensor is never handed to Warp
        with one_torch_thread(depth.device):
            torch.nan_to_num(depth, nan=_NO_DEPTH, posinf=_NO_DEPTH, neginf=_NO_DEPTH, out=buf.depth_inner)
        if self._graph is not None and buf.volume is not None:
            self._integrate_graph(rgb, buf)
        else:
            self._integrate_eager(rgb, buf, g)

    def _integrate_graph(self, rgb: torch.Tensor | None, buf: _FrameBuffers) -> None:
        """The frame as one graph replay (``tsdf.graph``): upload the params, copy the colour in, replay,
        read the state once. A frame whose new blocks did not fit changed nothing: grow, replay it."""
        launches, graph = self._launches, self._graph
        if not self._state_synced:  # after an eager frame (or none yet): the graph keeps the count from here
            launches.state[S_NUM_BLOCKS] = self.num_blocks
            launches.state[S_STAMP] = self._stamp
            self._state_synced = True
        self._reserve(self.num_blocks)
        launches.upload()
        while True:
            graph.bind(self, buf, self.cfg)
            if rgb is not None:
                graph.rgb.copy_(rgb)
            graph.launch()
            st = launches.read_state()  # the one host read (waits for the frame)
            if check_state(st) != SKIP_FULL:  # raises for a block beyond the key range
                break
            self._reserve(st[S_NUM_BLOCKS] + st[S_PARTS])
        self.hash.set_length(st[S_NUM_BLOCKS])
        self._stamp = st[S_STAMP]

    def _integrate_eager(self, rgb: torch.Tensor | None, buf: _FrameBuffers, g: _FrameGeometry) -> None:
        """``integrate`` in recorded Warp launches: mark the band's blocks (looking them up in the hash),
        select the old blocks to update, allocate the new blocks on the host and update the voxels of the
        selected and the new blocks. On the CPU the state is host memory (no reads), and with 2+ threads
        the marking overlaps the update of the surface blocks in view (``IntegrateLaunches.overlapped``);
        on CUDA the state is read once, after the selection."""
        cfg, launches = self.cfg, self._launches
        self._stamp += 1
        stamp, num_old = self._stamp, self.num_blocks
        self._state_synced = False
        launches.begin_host_frame(stamp, num_old)
        launches.upload()
        mark = None
        if buf.volume is not None:
            mark = dict(depth_pad_m=buf.depth, stride_px=cfg.allocation_stride, rays=buf.rays,
                        band_m=(-cfg.truncation_m, 0.0, cfg.truncation_m), carve_stride=cfg.carve_stride,
                        carve_step_m=cfg.free_space_step_m, side=2 * buf.r_blocks + 1,
                        depth_min_m=cfg.depth_min_m, depth_max_m=cfg.depth_max_m, volume_stamp=buf.volume_stamp,
                        keys=self.hash.key_buffer, key_slots=self.hash.key_slot_buffer, slot_stamp=self._slot_stamp,
                        new_keys=buf.new_keys)
        def select() -> dict:  # read when launched (the fallback's allocation may grow the storage)
            return dict(slot_stamp=self._slot_stamp, slot_coords=self.hash.slot_coord_buffer,
                        centre_scale=(0.5, cfg.block_size_m, 0.5 * cfg.voxel_size_m), radius_m=self.block_radius_m,
                        truncation_m=cfg.truncation_m, depth_min_m=cfg.depth_min_m, depth_max_m=cfg.depth_max_m,
                        depth_pad_m=buf.depth, has_surface=self.has_surface, selected=self._selected,
                        view_stamp=self._view_stamp)

        def update() -> dict:  # read when launched: the storage may have grown
            return dict(selected=self._selected, slot_coords=self.hash.slot_coord_buffer, block_voxels=cfg.block_voxels,
                        voxel_size_m=cfg.voxel_size_m, depth_pad_m=buf.depth, rgb=rgb, truncation_m=cfg.truncation_m,
                        depth_min_m=cfg.depth_min_m, depth_max_m=cfg.depth_max_m, max_weight=cfg.max_weight,
                        weight_ref_depth_m=cfg.weight_ref_depth_m, clear_free_space=cfg.clear_free_space,
                        dropoff_m=cfg.dropoff_m, tsdf=self.tsdf, weight=self.weight, color=self.color, updated=self.updated,
                        has_surface=self.has_surface)

        if mark is not None and self._can_overlap(buf, num_old):
            launches.overlapped(num_old=num_old, mark=mark, select=select(), update=lambda: voxel_values(
                launches, **update()), allocate=lambda st, drain: self._allocate_marked(st, buf, num_old, drain))
            return
        if mark is not None:
            launches.mark(**mark)
            if not launches.is_cuda and any(launches.part_counts(launches.read_state())[1]):
                raise_out_of_range()  # before the selection: the map is unchanged
        else:  # the depth range is too deep for a dense volume: the torch path's sort-based allocation
            slots = self._allocate(buf.depth_inner, buf, g)  # may grow the storage, _slot_stamp included
            self._slot_stamp[slots, 0] = stamp
        launches.select(num_old=num_old, **select())
        st = launches.read_state()  # on CUDA the one host read (it waits for the kernels so far)
        new = self._allocate_marked(st, buf, num_old) if mark is not None else self.num_blocks - num_old
        launches.set_new_blocks(new)
        launches.update_voxels(num_blocks=st[S_SELECTED] + new, **update())

    def _can_overlap(self, buf: _FrameBuffers, num_old: int) -> bool:
        """Whether the CPU frame may overlap its marking (``IntegrateLaunches.overlapped``): 2+ threads,
        blocks to update, and the dense volume (where marked cells are clamped) within the key range."""
        if self._launches.is_cuda or torch.get_num_threads() < 2 or num_old == 0:
            return False
        corner = self._launches.params_host["corner_index"][0]
        side = 2 * buf.r_blocks + 1
        return bool(np.all(np.abs(corner) < kernels.KEY_OFFSET)
                    and np.all(np.abs(corner + side - 1) < kernels.KEY_OFFSET))

    def _allocate_marked(self, st: list[int], buf: _FrameBuffers, num_old: int, drain=None) -> int:
        """Allocate the blocks the marking found new (from the read ``state``); the number of them.
        ``drain``: called before the storage or the hash grows (the overlapped frame's queued updates
        use the current tensors)."""
        new_counts, out_of_range = self._launches.part_counts(st)
        if any(out_of_range):
            raise_out_of_range()
        new = [buf.new_keys[p, :n] for p, n in enumerate(new_counts) if n]
        if new:
            if drain is not None and num_old + sum(new_counts) > min(self.hash.capacity, self.tsdf.shape[0]):
                drain()
            # each part's keys are distinct; a block new to two parts is in both lists
            if len(new) == 1:
                self.hash.append(new[0], presorted=False)  # slots num_old, num_old + 1, ... in key order
            else:
                self.hash.append(torch.unique(torch.cat(new)))
            self._grow(self.num_blocks)
        return self.num_blocks - num_old

    def clear_updated(self) -> torch.Tensor:
        """Slots of the blocks changed since the last call (and forget them)."""
        slots = torch.nonzero(self.updated[: self.num_blocks], as_tuple=True)[0]
        self.updated.zero_()
        return slots

    def dense(self, pad_voxels: int = 0, *, region_xy_m: tuple[float, float, float, float] | None = None,
              z_range_m: tuple[float, float] | None = None, color: bool = True) -> DenseGrid:
        """The allocated blocks' bounding box as dense (X, Y, Z) arrays; unallocated voxels are
        unobserved (weight 0, tsdf 1). Padding adds unobserved voxels around it. ``region_xy_m``
        (x_min, y_min, x_max, y_max) and ``z_range_m`` (z_min, z_max), world m: only the blocks that
        meet that box (the box of those blocks: cheaper than the whole map for a robot's surroundings);
        ``color=False`` leaves the colour out (an empty (X, Y, Z, 3) array). Runs its CPU torch ops on one
        thread (``torch_threads``: 63 against 226 ms for 723 blocks with 2 threads on a busy 2-core machine)."""
        with one_torch_thread(self.device):
            return self._dense(pad_voxels, region_xy_m, z_range_m, color)

    def _dense(self, pad_voxels: int, region_xy_m, z_range_m, color: bool) -> DenseGrid:
        b = self.cfg.block_voxels
        coords = self.hash.slot_coords
        if len(coords) == 0:
            raise ValueError("the map is empty: integrate frames before reading it")
        slots = None
        if region_xy_m is not None or z_range_m is not None:
            size, half = self.cfg.block_size_m, 0.5 * self.cfg.voxel_size_m
            lo_m = (coords * b).to(torch.float64) * self.cfg.voxel_size_m - half  # (n, 3) block's lower corner
            keep = torch.ones(len(coords), dtype=torch.bool, device=coords.device)
            boxes = []
            if region_xy_m is not None:
                x0, y0, x1, y1 = region_xy_m
                boxes += [(0, x0, x1), (1, y0, y1)]
            if z_range_m is not None:
                boxes.append((2, *z_range_m))
            for axis, a0, a1 in boxes:
                keep &= (lo_m[:, axis] + size >= a0) & (lo_m[:, axis] <= a1)
            slots = torch.nonzero(keep, as_tuple=True)[0]
            if len(slots) == 0:
                raise ValueError(f"no block of the map meets region_xy_m={region_xy_m}, z_range_m={z_range_m}: "
                                 "nothing mapped there yet")
            coords = coords[slots]
        lo = coords.min(0).values * b - pad_voxels
        hi = (coords.max(0).values + 1) * b + pad_voxels
        shape = tuple(int(s) for s in (hi - lo))
        tsdf = torch.ones(shape, dtype=torch.float32, device=self.device)
        weight = torch.zeros(shape, dtype=torch.float32, device=self.device)
        color_shape = (*shape, 3) if color else (0, 0, 0, 3)
        colors = torch.zeros(color_shape, dtype=torch.uint8, device=self.device)
        idx = (self.voxel_index(slots) - lo).reshape(-1, 3)
        rows = slice(0, self.num_blocks) if slots is None else slots
        tsdf[idx[:, 0], idx[:, 1], idx[:, 2]] = self.tsdf[rows].reshape(-1)
        weight[idx[:, 0], idx[:, 1], idx[:, 2]] = self.weight[rows].reshape(-1)
        if color:
            colors[idx[:, 0], idx[:, 1], idx[:, 2]] = self.color[rows].reshape(-1, 3)
        return DenseGrid(tsdf=tsdf, weight=weight, color=colors, origin_index=lo, voxel_size_m=self.cfg.voxel_size_m,
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


__all__ = ["DenseGrid", "TsdfCfg", "TsdfMap"]
