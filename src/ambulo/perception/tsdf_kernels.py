"""``TsdfMap.integrate``'s block allocation and per-voxel update as fused Warp kernels (CPU and CUDA).

Why kernels: the per-voxel update in eager torch is ~60 passes over every voxel of the frame's
blocks (~135k voxels at 640x480, 5 cm), each reading and writing whole temporaries, so memory
traffic and per-op overhead set its time. ``integrate_voxels`` reads a voxel's projection, its 1 + 4
depth pixels and its old state once and writes the new state once (as Open3D's ``VoxelBlockGrid``
and nvblox do); ``mark_band_blocks`` replaces ~15 torch ops of the allocation. Warp (``warp-lang``)
compiles both for the CPU (LLVM) and for CUDA from the same source, so the map stays device-generic:
launches go to the device and the current torch stream of the map's tensors, shared zero-copy.

The arithmetic is the torch path's (``TsdfMap._allocate``, ``TsdfMap._update_voxels_torch``)
operation by operation, so the two agree to float32 rounding: same projections (computed in torch
and passed in), same depth rule (nearest-pixel pre-filter, then bilinear unless the 2x2 cell spans a
depth edge), same free-space clearing, running average, weight saturation, round-half-to-even colour.
The kernels read the frame's own depth and colour: the torch path's padded copy (a 1-pixel border of
-1e9, non-finite depth as 0) is reproduced by ``padded_depth`` instead of written.

CPU: a Warp CPU launch runs on one thread, and each Warp thread reloads every kernel argument (a
uint8 or bool store may alias them), so on the CPU a thread does a whole block (or image row) in a
loop, and ``launch_voxel_update`` splits the blocks into one range per ``torch.get_num_threads()``
thread (the native call releases the GIL; ranges write disjoint voxels, the per-block flags are only
ever set True). No torch op in ``integrate``'s Warp path touches more than a few thousand elements:
a larger one would wake torch's OpenMP pool, whose threads then spin for milliseconds on the cores
these launches run on.

Compilation happens once per device on the first launch (seconds on the CPU, longer for CUDA) and
is cached on disk (Warp's kernel cache, ``WARP_CACHE_PATH``); time a benchmark after a warm-up frame.
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import torch

try:
    import warp as wp
except ImportError:  # TsdfMap falls back to its torch path
    wp = None

MAX_STEP = 0.05
"""Relative depth spread of a 2x2 pixel cell up to which the depth lookup interpolates (as tsdf.py)."""
NO_DEPTH = -1e9
"""Depth of the 1-pixel border around the image: a voxel projecting off the image reads it and is not
updated (as tsdf.py's padded buffer)."""

if wp is not None:

    @wp.func
    def padded_depth(depth_m: wp.array2d(dtype=wp.float32), r: int, c: int):
        """Depth at pixel (r, c) of the image padded by 1 pixel: NO_DEPTH on the border, 0 where not
        finite (the torch path's ``nan_to_num`` copy into its padded buffer)."""
        if r < 1 or c < 1 or r > depth_m.shape[0] or c > depth_m.shape[1]:
            return wp.float32(NO_DEPTH)
        d = depth_m[r - 1, c - 1]
        if not wp.isfinite(d):
            return wp.float32(0.0)
        return d

    @wp.kernel(enable_backward=False)
    def integrate_voxels(
        first_run: wp.int32,
        runs_per_block: wp.int32,
        voxels_per_run: wp.int32,
        slots: wp.array(dtype=wp.int64),
        origin_px: wp.array2d(dtype=wp.float32),
        local_px: wp.array2d(dtype=wp.float32),
        depth_m: wp.array2d(dtype=wp.float32),
        rgb: wp.array3d(dtype=wp.uint8),
        truncation_m: wp.float32,
        inv_truncation: wp.float32,
        depth_min_m: wp.float32,
        depth_max_m: wp.float32,
        max_weight: wp.float32,
        weight_ref_depth_m: wp.float32,
        clear_free_space: wp.int32,
        with_color: wp.int32,
        tsdf: wp.array2d(dtype=wp.float32),
        weight: wp.array2d(dtype=wp.float32),
        color: wp.array3d(dtype=wp.uint8),
        updated: wp.array(dtype=wp.bool),
        has_surface: wp.array(dtype=wp.bool),
    ):
        """Thread ``tid`` updates run ``first_run + tid``: ``voxels_per_run`` consecutive voxels of
        block i = run // ``runs_per_block`` (runs_per_block * voxels_per_run = V = B^3 voxels per block):
        one voxel per thread on CUDA, one block per thread on the CPU.

        slots: (n,) int64 storage slot of block i. origin_px: (3, n) float32 K' [R | t] of block i's
        origin and local_px: (3, V) K' R of each local offset (K' = K with the principal point shifted
        by the 1-pixel pad), so a voxel's homogeneous padded-pixel coordinates are their sum.
        depth_m: (H, W) float32 the frame's depth, m; rgb: (H, W, 3) uint8 its colour (read only when
        ``with_color``). tsdf, weight: (capacity, V) float32 and color: (capacity, V, 3) uint8, updated in
        place. updated, has_surface: (capacity,) bool set True where a voxel of the block was updated /
        holds tsdf < 0 (``has_surface[slots]`` is cleared before the launch)."""
        run = first_run + wp.tid()
        i = run // runs_per_block
        lv_first = (run - i * runs_per_block) * voxels_per_run
        slot = slots[i]
        ox = origin_px[0, i]
        oy = origin_px[1, i]
        oz = origin_px[2, i]
        width_px = float(depth_m.shape[1])
        height_px = float(depth_m.shape[0])
        any_updated = int(0)
        any_surface = int(0)
        for lv in range(lv_first, lv_first + voxels_per_run):
            old_t = tsdf[slot, lv]
            new_t = old_t
            x = ox + local_px[0, lv]
            y = oy + local_px[1, lv]
            z = oz + local_px[2, lv]
            zc = wp.max(z, 1.0e-6)
            # sub-pixel position in the padded image, clamped so the 2x2 cell stays inside it; anything
            # off the image lands on the border
            u = wp.clamp(x / zc, 0.0, width_px + 0.75)
            v = wp.clamp(y / zc, 0.0, height_px + 0.75)
            # 1. the nearest pixel bounds the interpolated depth within MAX_STEP: skip voxels that can
            # not be updated (most of a block lies behind the truncation band) without the 2x2 lookup
            d_near = padded_depth(depth_m, int(wp.rint(v)), int(wp.rint(u)))
            if d_near * (1.0 + MAX_STEP) >= z - truncation_m:
                # 2. bilinear where the 2x2 cell is valid and smooth, else the nearest pixel (no
                # blending across depth edges)
                u0 = wp.floor(u)
                v0 = wp.floor(v)
                fu = u - u0
                fv = v - v0
                r = int(v0)
                c = int(u0)
                d00 = padded_depth(depth_m, r, c)
                d01 = padded_depth(depth_m, r, c + 1)
                d10 = padded_depth(depth_m, r + 1, c)
                d11 = padded_depth(depth_m, r + 1, c + 1)
                lo = wp.min(wp.min(d00, d01), wp.min(d10, d11))
                hi = wp.max(wp.max(d00, d01), wp.max(d10, d11))
                rn = r + int(wp.rint(fv))
                cn = c + int(wp.rint(fu))
                d = padded_depth(depth_m, rn, cn)
                if hi <= lo * (1.0 + MAX_STEP) and lo >= depth_min_m and hi <= depth_max_m:
                    top = d00 + fu * (d01 - d00)
                    d = top + fv * ((d10 + fu * (d11 - d10)) - top)
                sdf = d - z
                # an updated voxel's nearest pixel (rn, cn) is inside the image: the border fails d >= min
                if sdf >= -truncation_m and d >= depth_min_m and d <= depth_max_m and z > 0.0:
                    # 3. free-space clearing, weighted running average, saturation
                    tsdf_obs = wp.min(sdf * inv_truncation, 1.0)
                    old_w = weight[slot, lv]
                    if clear_free_space != 0 and sdf >= truncation_m and old_t < 0.0:
                        old_w = 0.0
                    w_obs = 1.0
                    if weight_ref_depth_m > 0.0:
                        q = weight_ref_depth_m / zc
                        w_obs = wp.min(q * q, 1.0)
                    total = old_w + w_obs
                    blend = w_obs / (total + 1.0e-12)
                    new_t = old_t + blend * (tsdf_obs - old_t)
                    tsdf[slot, lv] = new_t
                    weight[slot, lv] = wp.min(total, max_weight)
                    if with_color != 0:
                        for ch in range(3):
                            old_c = float(color[slot, lv, ch])
                            obs_c = float(rgb[rn - 1, cn - 1, ch])
                            color[slot, lv, ch] = wp.uint8(int(wp.rint(old_c + blend * (obs_c - old_c))))
                    any_updated = 1
            if new_t < 0.0:
                any_surface = 1
        if any_updated != 0:
            updated[slot] = True
        if any_surface != 0:
            has_surface[slot] = True

    @wp.kernel(enable_backward=False)
    def mark_band_blocks(
        columns_per_run: wp.int32,
        depth_m: wp.array2d(dtype=wp.float32),
        stride_px: wp.int32,
        rays_blocks: wp.array3d(dtype=wp.float32),
        start_blocks: wp.array(dtype=wp.float32),
        band_m: wp.array(dtype=wp.float32),
        corner_blocks: wp.array(dtype=wp.float32),
        side: wp.int32,
        depth_min_m: wp.float32,
        depth_max_m: wp.float32,
        stamp: wp.int32,
        volume_stamp: wp.array(dtype=wp.int32),
        cells: wp.array(dtype=wp.int32),
        count: wp.array(dtype=wp.int32),
    ):
        """Block allocation: for every allocation pixel (r, c) = pixel (r s, c s), the volume cells of
        the blocks that the band [d - trunc, d + trunc] of its ray touches (3 samples; a block spans
        >= 2 trunc), with the float32 operations of ``TsdfMap._allocate``'s torch path. Each cell is
        listed once: the first sample to stamp it (``volume_stamp[cell]`` = this frame's ``stamp``, so
        the volume is never cleared) appends it to ``cells`` at ``count[0]``. Thread (r, j) does columns
        [j n, (j + 1) n) of row r, n = ``columns_per_run``: 1 on CUDA, a whole row on the CPU (one
        launch there, whose threads run one after the other: Warp's CPU atomics are not atomic).

        depth_m: (H, W) float32 raw depth (non-finite fails the range test). rays_blocks: (H/s, W/s, 3)
        world ray directions (z = 1 in the camera) in blocks per metre of depth. start_blocks: (3,) camera
        position in blocks + 0.5 / B (block = floor(round(p / voxel) / B) = floor(p / block + 0.5 / B)).
        band_m: (3,) -trunc, 0, trunc. corner_blocks: (3,) block coordinate of cell 0 of the dense
        (side^3,) volume of cells around the camera, x-major; samples outside are clamped in.
        cells: (>= number of cells hit,) int32 out; count: (1,) int32, zero before the launch."""
        r, run = wp.tid()
        c_first = run * columns_per_run
        for c in range(c_first, wp.min(c_first + columns_per_run, rays_blocks.shape[1])):
            d = depth_m[r * stride_px, c * stride_px]
            if d >= depth_min_m and d <= depth_max_m:
                for j in range(3):
                    dd = d + band_m[j]
                    cell = int(0)
                    for a in range(3):
                        sample = wp.floor(start_blocks[a] + rays_blocks[r, c, a] * dd)
                        k = wp.clamp(sample - corner_blocks[a], 0.0, float(side - 1))
                        cell = cell * side + int(k)
                    if volume_stamp[cell] != stamp:
                        if wp.atomic_exch(volume_stamp, cell, stamp) != stamp:
                            cells[wp.atomic_add(count, 0, 1)] = cell


def available() -> bool:
    """Whether Warp is importable (else ``TsdfMap`` falls back to its torch path)."""
    return wp is not None


_pool: ThreadPoolExecutor | None = None
"""Worker threads of split CPU launches (created on first use)."""


def _view(t: torch.Tensor, views: dict | None = None, name: str = ""):
    """A zero-copy Warp array over a torch tensor. ``views`` caches it by ``name`` for as long as the
    same tensor object is passed (the map's storage lives across frames; a replaced tensor replaces
    its cached view, so nothing stale is kept)."""
    if views is not None:
        hit = views.get(name)
        if hit is not None and hit[0] is t:
            return hit[1]
    if t.device.type == "cpu":  # the bare constructor: half the time of wp.from_torch (~15 us)
        a = wp.array(ptr=t.data_ptr(), dtype=wp.dtype_from_torch(t.dtype), shape=tuple(t.shape),
                     strides=tuple(st * t.element_size() for st in t.stride()), device="cpu", copy=False)
    else:
        a = wp.from_torch(t)
    if views is not None:
        views[name] = (t, a)
    return a


def _device(t: torch.Tensor):
    wp.init()  # no-op once initialised
    device = wp.device_from_torch(t.device)
    return device, (wp.stream_from_torch(t.device) if device.is_cuda else None)


def launch_voxel_update(*, slots: torch.Tensor, origin_px: torch.Tensor, local_px: torch.Tensor,
                        depth_m: torch.Tensor, rgb: torch.Tensor | None, truncation_m: float, depth_min_m: float,
                        depth_max_m: float, max_weight: float, weight_ref_depth_m: float | None,
                        clear_free_space: bool, tsdf: torch.Tensor, weight: torch.Tensor, color: torch.Tensor,
                        updated: torch.Tensor, has_surface: torch.Tensor, views: dict | None = None) -> None:
    """Run ``integrate_voxels`` over every voxel of ``slots`` (shapes as documented there; ``rgb``
    None: no colour) on the tensors' device: on CUDA in torch's current stream, on the CPU split over
    ``torch.get_num_threads()`` threads. ``views``: a dict the caller keeps, caching the Warp views of
    its long-lived tensors."""
    n_vox = local_px.shape[1]
    n_blocks = slots.numel()
    if n_blocks == 0:
        return
    device, stream = _device(tsdf)
    with_color = rgb is not None
    if rgb is None:
        rgb = views.setdefault("no_rgb", torch.zeros((1, 1, 3), dtype=torch.uint8, device=tsdf.device)) \
            if views is not None else torch.zeros((1, 1, 3), dtype=torch.uint8, device=tsdf.device)
    common = [
        _view(slots), _view(origin_px), _view(local_px), _view(depth_m), _view(rgb), float(truncation_m),
        float(1.0 / truncation_m), float(depth_min_m), float(depth_max_m), float(max_weight),
        float(weight_ref_depth_m or 0.0), int(clear_free_space), int(with_color),
        _view(tsdf, views, "tsdf"), _view(weight, views, "weight"), _view(color, views, "color"),
        _view(updated, views, "updated"), _view(has_surface, views, "has_surface"),
    ]
    if device.is_cuda:  # a thread per voxel, in torch's stream so it is ordered with the torch ops around it
        wp.launch(integrate_voxels, dim=n_blocks * n_vox, inputs=[0, n_vox, 1, *common], device=device,
                  stream=stream)
        return
    # CPU: a thread per block, the blocks in contiguous chunks that torch.get_num_threads() threads take
    # in turn (dynamic, so a thread the OS does not schedule soon does not hold the others up: the caller
    # waits only for chunks already taken); one launch when too few blocks to pay for the hand-off
    parts = max(1, min(torch.get_num_threads(), n_blocks // 32))
    if parts == 1:
        wp.launch(integrate_voxels, dim=n_blocks, inputs=[0, 1, n_vox, *common], device=device)
        return
    chunks = 2 * parts
    bounds = [n_blocks * c // chunks for c in range(chunks + 1)]
    state = {"next": 0, "running": 0, "error": None}
    done = threading.Condition()

    def work() -> None:
        while True:
            with done:
                c = state["next"]
                if c >= chunks:
                    return
                state["next"] += 1
                state["running"] += 1
            try:
                wp.launch(integrate_voxels, dim=bounds[c + 1] - bounds[c], inputs=[bounds[c], 1, n_vox, *common],
                          device=device)
            except BaseException as e:  # re-raised by the calling thread
                state["error"] = e
                raise
            finally:
                with done:
                    state["running"] -= 1
                    done.notify_all()

    global _pool
    if _pool is None or _pool._max_workers < parts - 1:
        _pool = ThreadPoolExecutor(max_workers=parts - 1, thread_name_prefix="ambulo-tsdf")
    for _ in range(parts - 1):
        _pool.submit(work)
    work()
    with done:
        done.wait_for(lambda: state["running"] == 0)
    if state["error"] is not None:
        raise state["error"]


def launch_mark_band_blocks(*, depth_m: torch.Tensor, stride_px: int, rays_blocks: torch.Tensor,
                            start_blocks: torch.Tensor, band_m: torch.Tensor, corner_blocks: torch.Tensor, side: int,
                            depth_min_m: float, depth_max_m: float, stamp: int, volume_stamp: torch.Tensor,
                            cells: torch.Tensor, count: torch.Tensor, views: dict | None = None) -> None:
    """Run ``mark_band_blocks`` (shapes as documented there) on the tensors' device (torch's stream on
    CUDA); ``count`` must be zero."""
    device, stream = _device(volume_stamp)
    rows, columns = rays_blocks.shape[:2]
    per_run = 1 if device.is_cuda else columns
    wp.launch(mark_band_blocks, dim=(rows, (columns + per_run - 1) // per_run), device=device, stream=stream, inputs=[
        per_run, _view(depth_m), int(stride_px), _view(rays_blocks), _view(start_blocks), _view(band_m, views, "band"),
        _view(corner_blocks), int(side), float(depth_min_m), float(depth_max_m), int(stamp),
        _view(volume_stamp, views, "volume_stamp"), _view(cells, views, "cells"), _view(count, views, "count")])


__all__ = ["MAX_STEP", "NO_DEPTH", "available", "launch_mark_band_blocks", "launch_voxel_update"]
