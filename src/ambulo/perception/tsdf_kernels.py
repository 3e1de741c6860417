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
The voxel kernel reads the torch path's padded depth copy (a 1-pixel border of -1e9, non-finite as 0;
one torch op, 0.05-0.08 ms, where a Warp copy kernel took ~1 ms and bounds checks in the voxel kernel
~0.9 ms more) and the frame's own colour. The small per-frame matrices are computed once on the host
and passed by value, so ``integrate`` needs no upload and two host reads of counters.

CPU: a Warp CPU launch runs on one thread, and each Warp thread reloads every kernel argument (a
uint8 or bool store may alias them), so on the CPU a thread does a whole block (or image row) in a
loop, and ``launch_voxel_update`` splits the blocks into one range per ``torch.get_num_threads()``
thread (the native call releases the GIL; ranges write disjoint voxels, the per-block flags are only
ever set True). Apart from the padded depth copy, no torch op in ``integrate``'s Warp path touches
more than a few thousand elements (a larger one wakes torch's OpenMP pool, whose threads may spin on
the cores these launches run on; scoping that copy to one thread measured no better).

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

KEY_OFFSET = 1 << 19
"""A block key holds block coordinates offset by this, 20 bits per axis (``block_hash.encode``; the
Warp-vs-torch test would see other keys as other blocks)."""

if wp is not None:

    @wp.func
    def block_key(x: int, y: int, z: int):
        """``block_hash.encode`` of block (x, y, z)."""
        return ((wp.int64(x + KEY_OFFSET) << wp.int64(40)) | (wp.int64(y + KEY_OFFSET) << wp.int64(20))
                | wp.int64(z + KEY_OFFSET))

    @wp.func
    def find_slot(keys: wp.array(dtype=wp.int64), key_slots: wp.array(dtype=wp.int64), num_keys: int, key: wp.int64):
        """Slot of ``key`` in the hash's sorted ``keys`` (binary search, as ``BlockHash.find``); -1 if absent."""
        lo = int(0)
        hi = num_keys
        while lo < hi:
            mid = (lo + hi) // 2
            if keys[mid] < key:
                lo = mid + 1
            else:
                hi = mid
        slot = int(-1)
        if lo < num_keys:
            if keys[lo] == key:
                slot = int(key_slots[lo])
        return slot

    @wp.kernel(enable_backward=False)
    def mark_band_blocks(
        columns_per_run: wp.int32,
        depth_m: wp.array2d(dtype=wp.float32),
        stride_px: wp.int32,
        rays: wp.array3d(dtype=wp.float32),
        rot_blocks: wp.mat33,
        start_blocks: wp.vec3,
        band_m: wp.vec3,
        corner_blocks: wp.vec3,
        corner_index: wp.vec3i,
        side: wp.int32,
        depth_min_m: wp.float32,
        depth_max_m: wp.float32,
        stamp: wp.int32,
        volume_stamp: wp.array(dtype=wp.int32),
        keys: wp.array(dtype=wp.int64),
        key_slots: wp.array(dtype=wp.int64),
        num_keys: wp.int32,
        slot_stamp: wp.array(dtype=wp.int32),
        new_keys: wp.array(dtype=wp.int64),
        count: wp.array(dtype=wp.int32),
    ):
        """Block allocation: for every allocation pixel (r, c) = pixel (r s, c s), the volume cells of
        the blocks that the band [d - trunc, d + trunc] of its ray touches (3 samples; a block spans
        >= 2 trunc), with the float32 operations of ``TsdfMap._allocate``'s torch path. A cell is looked
        at once per frame: the first sample to stamp it (``volume_stamp[cell]`` = ``stamp``, so the volume
        is never cleared) looks its block up in the hash: an allocated block gets ``slot_stamp[slot] =
        stamp``, a new one's key is appended to ``new_keys`` at ``count[0]``. Thread (r, j) does columns
        [j n, (j + 1) n) of row r, n = ``columns_per_run``: 1 on CUDA, a whole row on the CPU (one
        launch there, whose threads run one after the other: Warp's CPU atomics are not atomic).

        depth_m: (H, W) float32 raw depth (non-finite fails the range test). rays: (H/s, W/s, 3) camera
        rays (z = 1) of the allocation pixels. rot_blocks: R_wc^T / block size, so a ray's world
        direction in blocks per metre is component a = sum_i ray_i rot_blocks[i, a]. start_blocks: camera
        position in blocks + 0.5 / B (block = floor(round(p / voxel) / B) = floor(p / block + 0.5 / B)).
        band_m: -trunc, 0, trunc. corner_blocks / corner_index: block coordinate of cell 0 of the dense
        side^3 volume of cells around the camera, x-major; samples outside are clamped in.
        keys, key_slots: the hash's (num_keys,) sorted keys and their slots (length >= 1).
        slot_stamp: (capacity,) int32. new_keys: (side^3,) int64 out; count: (3,) int32, zero before
        (count[2]: cells beyond the key range, ``BlockHash.insert``'s error)."""
        r, run = wp.tid()
        c_first = run * columns_per_run
        for c in range(c_first, wp.min(c_first + columns_per_run, rays.shape[1])):
            d = depth_m[r * stride_px, c * stride_px]
            if d >= depth_min_m and d <= depth_max_m:
                rx = rays[r, c, 0]
                ry = rays[r, c, 1]
                rz = rays[r, c, 2]
                for j in range(3):
                    dd = d + band_m[j]
                    cell = int(0)
                    for a in range(3):
                        ray_a = rx * rot_blocks[0, a] + ry * rot_blocks[1, a] + rz * rot_blocks[2, a]
                        sample = wp.floor(start_blocks[a] + ray_a * dd)
                        k = wp.clamp(sample - corner_blocks[a], 0.0, float(side - 1))
                        cell = cell * side + int(k)
                    if volume_stamp[cell] != stamp:
                        if wp.atomic_exch(volume_stamp, cell, stamp) != stamp:
                            bx = corner_index[0] + cell // (side * side)
                            by = corner_index[1] + (cell // side) % side
                            bz = corner_index[2] + cell % side
                            if wp.max(wp.max(wp.abs(bx), wp.abs(by)), wp.abs(bz)) >= KEY_OFFSET:
                                wp.atomic_add(count, 2, 1)  # beyond the key range: integrate raises
                            else:
                                key = block_key(bx, by, bz)
                                slot = find_slot(keys, key_slots, num_keys, key)
                                if slot >= 0:
                                    slot_stamp[slot] = stamp
                                else:
                                    new_keys[wp.atomic_add(count, 0, 1)] = key

    @wp.kernel(enable_backward=False)
    def select_blocks(
        slots_per_run: wp.int32,
        num_blocks: wp.int32,
        num_old: wp.int32,
        stamp: wp.int32,
        slot_stamp: wp.array(dtype=wp.int32),
        slot_coords: wp.array2d(dtype=wp.int64),
        rot_cw: wp.mat33,
        t_cw: wp.vec3,
        k: wp.vec4,
        centre_scale: wp.vec3,
        radius_m: wp.float32,
        radius_px_m: wp.float32,
        truncation_m: wp.float32,
        depth_min_m: wp.float32,
        depth_max_m: wp.float32,
        depth_m: wp.array2d(dtype=wp.float32),
        has_surface: wp.array(dtype=wp.bool),
        selected: wp.array(dtype=wp.int64),
        count: wp.array(dtype=wp.int32),
    ):
        """The blocks this frame updates, appended to ``selected`` at ``count[1]`` (ascending on the CPU):
        new blocks (slot >= ``num_old``), blocks stamped by ``mark_band_blocks``, and blocks holding a
        surface that the view may clear (``TsdfMap._blocks_in_view``, the same float32 operations).
        ``has_surface`` of a selected block is cleared (the voxel update sets it again). Thread ``tid``
        does slots [tid n, (tid + 1) n), n = ``slots_per_run`` (1 on CUDA, all on the CPU).

        slot_coords: (capacity, 3) int64 block coordinates. rot_cw, t_cw: world-to-camera. k: fx, fy, cx,
        cy. centre_scale: (0.5, block size, half a voxel): a block's centre is (b + 0.5) size - half voxel.
        radius_m: half a block's diagonal, radius_px_m = radius_m fx. depth_m: (H, W) float32 raw depth."""
        first = wp.tid() * slots_per_run
        h = depth_m.shape[0]
        w = depth_m.shape[1]
        for i in range(first, wp.min(first + slots_per_run, num_blocks)):
            keep = i >= num_old or slot_stamp[i] == stamp
            if not keep and has_surface[i]:
                bx = (float(slot_coords[i, 0]) + centre_scale[0]) * centre_scale[1] - centre_scale[2]
                by = (float(slot_coords[i, 1]) + centre_scale[0]) * centre_scale[1] - centre_scale[2]
                bz = (float(slot_coords[i, 2]) + centre_scale[0]) * centre_scale[1] - centre_scale[2]
                px = bx * rot_cw[0, 0] + by * rot_cw[0, 1] + bz * rot_cw[0, 2] + t_cw[0]
                py = bx * rot_cw[1, 0] + by * rot_cw[1, 1] + bz * rot_cw[1, 2] + t_cw[1]
                z = bx * rot_cw[2, 0] + by * rot_cw[2, 1] + bz * rot_cw[2, 2] + t_cw[2]
                zc = wp.max(z, 1.0e-3)
                u = int(wp.rint(px / zc * k[0] + k[2]))
                v = int(wp.rint(py / zc * k[1] + k[3]))
                margin = int((1.0 / zc) * radius_px_m)
                near = z + radius_m > depth_min_m and z - radius_m < depth_max_m
                inside = u + margin >= 0 and u - margin < w and v + margin >= 0 and v - margin < h
                if near and inside and z > 0.0:
                    d = depth_m[wp.clamp(v, 0, h - 1), wp.clamp(u, 0, w - 1)]
                    valid = d >= depth_min_m and d <= depth_max_m
                    keep = not valid or z - radius_m < d + truncation_m
            if keep:
                selected[wp.atomic_add(count, 1, 1)] = wp.int64(i)
                has_surface[i] = False

    @wp.kernel(enable_backward=False)
    def integrate_voxels(
        first_run: wp.int32,
        runs_per_block: wp.int32,
        voxels_per_run: wp.int32,
        slots: wp.array(dtype=wp.int64),
        slot_coords: wp.array2d(dtype=wp.int64),
        block_voxels: wp.int32,
        voxel_size_m: wp.float32,
        kr: wp.mat33,
        kt: wp.vec3,
        local_px: wp.array2d(dtype=wp.float32),
        depth_pad_m: wp.array2d(dtype=wp.float32),
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

        slots: (n,) int64 storage slot of block i; slot_coords: (capacity, 3) int64 block coordinates.
        kr, kt: K' R_cw and K' t_cw (K' = K with the principal point shifted by the 1-pixel pad), so the
        homogeneous padded-pixel coordinates of block i's origin o = coords B voxel are kr o + kt (summed
        as ``TsdfMap._project``), and a voxel's are that plus local_px: (3, V) float32 K' R of each local
        offset. depth_pad_m: (H + 2, W + 2) float32 the frame's depth (non-finite as 0) inside a 1-pixel
        NO_DEPTH border, read without bounds checks; rgb: (H, W, 3) uint8 the frame's colour (read only
        when ``with_color``; it needs no padded copy: only updated voxels read it, and their nearest pixel
        is inside the image, as the border fails the depth range test). tsdf, weight: (capacity, V) float32 and color:
        (capacity, V, 3) uint8, updated in place. updated, has_surface: (capacity,) bool set True where a
        voxel of the block was updated / holds tsdf < 0 (``select_blocks`` cleared ``has_surface``)."""
        run = first_run + wp.tid()
        i = run // runs_per_block
        lv_first = (run - i * runs_per_block) * voxels_per_run
        slot = slots[i]
        x0 = float(slot_coords[slot, 0] * wp.int64(block_voxels)) * voxel_size_m
        y0 = float(slot_coords[slot, 1] * wp.int64(block_voxels)) * voxel_size_m
        z0 = float(slot_coords[slot, 2] * wp.int64(block_voxels)) * voxel_size_m
        ox = kr[0, 0] * x0 + kr[0, 1] * y0 + kr[0, 2] * z0 + kt[0]
        oy = kr[1, 0] * x0 + kr[1, 1] * y0 + kr[1, 2] * z0 + kt[1]
        oz = kr[2, 0] * x0 + kr[2, 1] * y0 + kr[2, 2] * z0 + kt[2]
        width_px = float(depth_pad_m.shape[1] - 2)
        height_px = float(depth_pad_m.shape[0] - 2)
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
            # off the image lands on the NO_DEPTH border
            u = wp.clamp(x / zc, 0.0, width_px + 0.75)
            v = wp.clamp(y / zc, 0.0, height_px + 0.75)
            # 1. the nearest pixel bounds the interpolated depth within MAX_STEP: skip voxels that can
            # not be updated (most of a block lies behind the truncation band) without the 2x2 lookup
            d_near = depth_pad_m[int(wp.rint(v)), int(wp.rint(u))]
            if d_near * (1.0 + MAX_STEP) >= z - truncation_m:
                # 2. bilinear where the 2x2 cell is valid and smooth, else the nearest pixel (no
                # blending across depth edges)
                u0 = wp.floor(u)
                v0 = wp.floor(v)
                fu = u - u0
                fv = v - v0
                r = int(v0)
                c = int(u0)
                d00 = depth_pad_m[r, c]
                d01 = depth_pad_m[r, c + 1]
                d10 = depth_pad_m[r + 1, c]
                d11 = depth_pad_m[r + 1, c + 1]
                lo = wp.min(wp.min(d00, d01), wp.min(d10, d11))
                hi = wp.max(wp.max(d00, d01), wp.max(d10, d11))
                rn = r + int(wp.rint(fv))
                cn = c + int(wp.rint(fu))
                d = depth_pad_m[rn, cn]
                if hi <= lo * (1.0 + MAX_STEP) and lo >= depth_min_m and hi <= depth_max_m:
                    top = d00 + fu * (d01 - d00)
                    d = top + fv * ((d10 + fu * (d11 - d10)) - top)
                sdf = d - z
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
                            obs_c = float(rgb[rn - 1, cn - 1, ch])  # (rn, cn) is inside the image
                            color[slot, lv, ch] = wp.uint8(int(wp.rint(old_c + blend * (obs_c - old_c))))
                    any_updated = 1
            if new_t < 0.0:
                any_surface = 1
        if any_updated != 0:
            updated[slot] = True
        if any_surface != 0:
            has_surface[slot] = True


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


def _mat33(m) -> "wp.mat33":
    """A (3, 3) float32 array as a launch argument, passed by value (no upload, no torch op)."""
    return wp.mat33(*(float(x) for x in m.reshape(-1)))


def _vec3(v) -> "wp.vec3":
    return wp.vec3(*(float(x) for x in v))


def launch_mark_band_blocks(*, depth_m: torch.Tensor, stride_px: int, rays: torch.Tensor, rot_blocks, start_blocks,
                            band_m, corner_blocks, corner_index, side: int, depth_min_m: float, depth_max_m: float,
                            stamp: int, volume_stamp: torch.Tensor, keys: torch.Tensor, key_slots: torch.Tensor,
                            num_keys: int, slot_stamp: torch.Tensor, new_keys: torch.Tensor, counts: torch.Tensor,
                            views: dict | None = None) -> None:
    """Run ``mark_band_blocks`` (shapes as documented there; the small per-frame constants as (3, 3) /
    (3,) host arrays, passed by value) on the tensors' device (torch's stream on CUDA)."""
    device, stream = _device(volume_stamp)
    rows, columns = rays.shape[:2]
    per_run = 1 if device.is_cuda else columns
    wp.launch(mark_band_blocks, dim=(rows, (columns + per_run - 1) // per_run), device=device, stream=stream, inputs=[
        per_run, _view(depth_m), int(stride_px), _view(rays, views, "rays"), _mat33(rot_blocks), _vec3(start_blocks),
        _vec3(band_m), _vec3(corner_blocks), wp.vec3i(*(int(c) for c in corner_index)), int(side), float(depth_min_m),
        float(depth_max_m), int(stamp), _view(volume_stamp, views, "volume_stamp"), _view(keys, views, "keys"),
        _view(key_slots, views, "key_slots"), int(num_keys), _view(slot_stamp, views, "slot_stamp"),
        _view(new_keys, views, "new_keys"), _view(counts, views, "counts")])


def launch_select_blocks(*, num_blocks: int, num_old: int, stamp: int, slot_stamp: torch.Tensor,
                         slot_coords: torch.Tensor, rot_cw, t_cw, k4, centre_scale, radius_m: float, radius_px_m: float,
                         truncation_m: float, depth_min_m: float, depth_max_m: float, depth_m: torch.Tensor,
                         has_surface: torch.Tensor, selected: torch.Tensor, counts: torch.Tensor,
                         views: dict | None = None) -> None:
    """Run ``select_blocks`` over slots [0, num_blocks) (shapes as documented there)."""
    if num_blocks == 0:
        return
    device, stream = _device(slot_stamp)
    per_run = 1 if device.is_cuda else num_blocks
    wp.launch(select_blocks, dim=(num_blocks + per_run - 1) // per_run, device=device, stream=stream, inputs=[
        per_run, int(num_blocks), int(num_old), int(stamp), _view(slot_stamp, views, "slot_stamp"),
        _view(slot_coords, views, "slot_coords"), _mat33(rot_cw), _vec3(t_cw), wp.vec4(*(float(x) for x in k4)),
        _vec3(centre_scale), float(radius_m), float(radius_px_m), float(truncation_m), float(depth_min_m),
        float(depth_max_m), _view(depth_m), _view(has_surface, views, "has_surface"),
        _view(selected, views, "selected"), _view(counts, views, "counts")])


def launch_voxel_update(*, slots: torch.Tensor, slot_coords: torch.Tensor, block_voxels: int, voxel_size_m: float,
                        kr, kt, local_px: torch.Tensor, depth_pad_m: torch.Tensor, rgb: torch.Tensor | None, truncation_m: float, depth_min_m: float, depth_max_m: float,
                        max_weight: float, weight_ref_depth_m: float | None, clear_free_space: bool,
                        tsdf: torch.Tensor, weight: torch.Tensor, color: torch.Tensor, updated: torch.Tensor,
                        has_surface: torch.Tensor, views: dict | None = None) -> None:
    """Run ``integrate_voxels`` over every voxel of ``slots`` (shapes as documented there; kr (3, 3) and
    kt (3,) host float32 arrays; ``rgb`` None: no colour) on the tensors' device: on CUDA in torch's current stream, on the CPU
    split over ``torch.get_num_threads()`` threads. ``views``: a dict the caller keeps, caching the Warp
    views of its long-lived tensors."""
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
        _view(slots), _view(slot_coords, views, "slot_coords"), int(block_voxels), float(voxel_size_m), _mat33(kr),
        _vec3(kt), _view(local_px), _view(depth_pad_m, views, "depth_pad"), _view(rgb),
        float(truncation_m), float(1.0 / truncation_m), float(depth_min_m), float(depth_max_m), float(max_weight),
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
    wp.load_module(integrate_voxels.module, device=device)  # once, before threads race to compile it
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


__all__ = ["KEY_OFFSET", "MAX_STEP", "NO_DEPTH", "available", "launch_mark_band_blocks", "launch_select_blocks",
           "launch_voxel_update"]
