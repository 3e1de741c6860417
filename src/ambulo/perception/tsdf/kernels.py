"""``TsdfMap.integrate``'s block allocation and per-voxel update as fused Warp kernels (CPU and CUDA).

Why kernels: the per-voxel update in eager torch is ~60 passes over every voxel of the frame's
blocks (~135k voxels at 640x480, 5 cm), each reading and writing whole temporaries, so memory
traffic and per-op overhead set its time. ``integrate_voxels`` reads a voxel's projection, its 1 + 4
depth pixels and its old state once and writes the new state once (as Open3D's ``VoxelBlockGrid``
and nvblox do); ``mark_band_blocks`` replaces ~15 torch ops of the allocation. Warp (``warp-lang``)
compiles both for the CPU (LLVM) and for CUDA from the same source, so the map stays device-generic:
launches go to the device and the current torch stream of the map's tensors, shared zero-copy.

The arithmetic is the torch path's (``tsdf.reference``: ``TsdfMap._allocate``, ``_update_voxels_torch``)
operation by operation, so the two agree to float32 rounding: same projections (computed in torch
and passed in), same depth rule (nearest-pixel pre-filter, then bilinear unless the 2x2 cell spans a
depth edge), same free-space clearing, running average, weight saturation, round-half-to-even colour.
All three kernels read the torch path's padded depth copy (a 1-pixel border of -1e9, non-finite
readings as -1e9 too, which fails every depth range test as they do; one torch op, 0.05-0.08 ms,
where a Warp copy kernel took ~1 ms and bounds checks in the voxel kernel ~0.9 ms more) and the
voxel kernel the frame's own colour. The small per-frame matrices are computed once on the host and
read from a one-element ``FrameParams`` array and the frame's counters and stamp from an int32
``state`` array (``S_*``), so a launch's arguments need not change from frame to frame: on CUDA the
whole frame is one captured graph (``tsdf.graph``), on the CPU recorded launches (``tsdf.launches``).
The new blocks' slots follow the selected ones: no second selection pass.

On the CPU a Warp launch runs on one thread, and each Warp thread reloads every kernel argument (a
uint8 or bool store may alias them), so there a kernel thread does a whole block (or image row) in a
loop; Warp's CPU atomics (``atomic_cas`` included) are plain read-modify-writes, so ``mark_band_blocks``
can only be split race-free by giving each range its own outputs (its ``part``). How the launches are
recorded, replayed and split over threads is ``tsdf.launches``.

Compilation happens once per device on the first launch (seconds on the CPU, longer for CUDA) and
is cached on disk (Warp's kernel cache, ``WARP_CACHE_PATH``); time a benchmark after a warm-up frame.
"""

from __future__ import annotations

try:
    import warp as wp
except ImportError:  # TsdfMap falls back to its torch path
    wp = None

MAX_STEP = 0.05
"""Relative depth spread of a 2x2 pixel cell up to which the depth lookup interpolates (as the
torch path, ``tsdf.reference``)."""
NO_DEPTH = -1e9
"""Depth of the 1-pixel border around the image: a voxel projecting off the image reads it and is not
updated (as ``tsdf.frame``'s padded buffer)."""

KEY_OFFSET = 1 << 19
"""A block key holds block coordinates offset by this, 20 bits per axis (``block_hash.encode``; the
Warp-vs-torch test would see other keys as other blocks)."""

S_SELECTED = 0
"""``state`` entries (an int32 array the kernels share with the host): old blocks the frame updates ..."""
S_STAMP = 1
"""... the frame's stamp (a volume cell / slot holding it was marked this frame) ..."""
S_NUM_BLOCKS = 2
"""... blocks allocated before this frame (the new ones take slots from here on) ..."""
S_NEW_BLOCKS = 3
"""... new blocks the voxel update covers ..."""
S_SKIP = 4
"""... non-zero when the frame changes nothing: SKIP_FULL or SKIP_OUT_OF_RANGE ..."""
S_PARTS = 5
"""... then per part p of ``mark_band_blocks`` its new keys at S_PARTS + 2 p and its cells beyond the
key range at S_PARTS + 2 p + 1."""
SKIP_FULL = 1
"""The new blocks do not fit the storage (the host grows it and integrates the frame again)."""
SKIP_OUT_OF_RANGE = 2
"""A block beyond the key range (the host raises)."""


SELECT_BOTH = 0
"""``select_blocks``: the band's blocks and the surface blocks in view ..."""
SELECT_VIEW = 1
"""... only the surface blocks in view ..."""
SELECT_BAND = 2
"""... only the band's blocks that SELECT_VIEW did not select."""


def state_size(parts: int) -> int:
    return S_PARTS + 2 * parts


if wp is not None:

    @wp.struct
    class FrameParams:
        """A frame's small matrices, read by the kernels from a one-element array (host memory on the
        CPU, device memory on CUDA, where a captured graph replays with whatever it holds)."""

        rot_blocks: wp.mat33
        """R_wc^T / block size: a ray's world direction in blocks per metre is ray @ rot_blocks."""
        start_blocks: wp.vec3
        """Camera position in blocks + 0.5 / B."""
        corner_blocks: wp.vec3
        """Block coordinate of cell 0 of the dense volume around the camera (float)..."""
        corner_index: wp.vec3i
        """... and as integers."""
        rot_cw: wp.mat33
        """World-to-camera rotation; t_cw its translation, m."""
        t_cw: wp.vec3
        k: wp.vec4
        """fx, fy, cx, cy, px."""
        radius_px_m: wp.float32
        """Half a block's diagonal times fx."""
        kr: wp.mat33
        """K' R_cw, K' = K with the principal point shifted by the 1-pixel pad; kt = K' t_cw."""
        kt: wp.vec3
        with_color: wp.int32

    @wp.func
    def block_key(x: int, y: int, z: int):
        """``block_hash.encode`` of block (x, y, z)."""
        return ((wp.int64(x + KEY_OFFSET) << wp.int64(40)) | (wp.int64(y + KEY_OFFSET) << wp.int64(20))
                | wp.int64(z + KEY_OFFSET))

    @wp.func
    def count_below(keys: wp.array(dtype=wp.int64), n: int, key: wp.int64):
        """Entries of the sorted ``keys[:n]`` below ``key`` (a binary search)."""
        lo = int(0)
        hi = n
        while lo < hi:
            mid = (lo + hi) // 2
            if keys[mid] < key:
                lo = mid + 1
            else:
                hi = mid
        return lo

    @wp.func
    def find_slot(keys: wp.array(dtype=wp.int64), key_slots: wp.array(dtype=wp.int64), num_keys: int, key: wp.int64):
        """Slot of ``key`` in the hash's sorted ``keys`` (as ``BlockHash.find``); -1 if absent."""
        lo = count_below(keys, num_keys, key)
        slot = int(-1)
        if lo < num_keys:
            if keys[lo] == key:
                slot = int(key_slots[lo])
        return slot

    @wp.func
    def mark_sample(dd: float, ray_w: wp.vec3, prm: FrameParams, side: int, part: int, stamp: int, num_keys: int,
                    volume_stamp: wp.array2d(dtype=wp.int32), keys: wp.array(dtype=wp.int64),
                    key_slots: wp.array(dtype=wp.int64), slot_stamp: wp.array2d(dtype=wp.int32),
                    new_keys: wp.array2d(dtype=wp.int64), state: wp.array(dtype=wp.int32)):
        """``mark_band_blocks``' work for the sample at depth ``dd`` along a ray (``ray_w``: its world
        direction in blocks per metre): the first sample of the frame and part in its volume cell looks
        the cell's block up; an allocated one is stamped, a new one's key appended."""
        cell = int(0)
        for a in range(3):
            sample = wp.floor(prm.start_blocks[a] + ray_w[a] * dd)
            k = wp.clamp(sample - prm.corner_blocks[a], 0.0, float(side - 1))
            cell = cell * side + int(k)
        if volume_stamp[part, cell] != stamp:
            if wp.atomic_exch(volume_stamp, part, cell, stamp) != stamp:
                bx = prm.corner_index[0] + cell // (side * side)
                by = prm.corner_index[1] + (cell // side) % side
                bz = prm.corner_index[2] + cell % side
                if wp.max(wp.max(wp.abs(bx), wp.abs(by)), wp.abs(bz)) >= KEY_OFFSET:
                    wp.atomic_add(state, S_PARTS + 2 * part + 1, 1)  # beyond the key range
                else:
                    key = block_key(bx, by, bz)
                    slot = find_slot(keys, key_slots, num_keys, key)
                    if slot >= 0:
                        slot_stamp[slot, part] = stamp
                    else:
                        new_keys[part, wp.atomic_add(state, S_PARTS + 2 * part, 1)] = key
        return 0

    @wp.kernel(enable_backward=False)
    def mark_band_blocks(
        first_row: wp.int32,
        part: wp.int32,
        columns_per_run: wp.int32,
        depth_pad_m: wp.array2d(dtype=wp.float32),
        stride_px: wp.int32,
        rays: wp.array3d(dtype=wp.float32),
        params: wp.array(dtype=FrameParams),
        band_m: wp.vec3,
        carve_stride: wp.int32,
        carve_step_m: wp.float32,
        side: wp.int32,
        depth_min_m: wp.float32,
        depth_max_m: wp.float32,
        volume_stamp: wp.array2d(dtype=wp.int32),
        keys: wp.array(dtype=wp.int64),
        key_slots: wp.array(dtype=wp.int64),
        slot_stamp: wp.array2d(dtype=wp.int32),
        new_keys: wp.array2d(dtype=wp.int64),
        state: wp.array(dtype=wp.int32),
    ):
        """Block allocation: for every allocation pixel (r, c) = pixel (r s, c s), the volume cells of
        the blocks that the band [d - trunc, d + trunc] of its ray touches (3 samples; a block spans
        >= 2 trunc), with the float32 operations of ``TsdfMap._allocate``'s torch path. A cell is looked
        at once per frame and ``part``: the first sample to stamp it (``volume_stamp[part, cell]`` = the
        frame's stamp, so the volume is never cleared) looks its block up in the hash (its first
        ``state[S_NUM_BLOCKS]`` sorted keys): an allocated block gets ``slot_stamp[slot, part] = stamp``,
        a new one's key is appended to ``new_keys[part]`` at ``state[S_PARTS + 2 part]``. Thread (r, j)
        does columns [j n, (j + 1) n) of row ``first_row`` + r, n = ``columns_per_run``: 1 on CUDA (one
        launch, part 0: real atomics), a whole row on the CPU, where a launch's threads run one after the
        other on one OS thread and Warp's CPU atomics are plain read-modify-writes (``atomic_cas`` too):
        there the rows may be split into ``PARTS`` launches run concurrently, each with its own part of
        every output, so no two OS threads write the same element (a block new to two parts is in both
        key lists; the caller merges them).

        depth_pad_m: (H + 2, W + 2) float32 the padded depth (non-finite as NO_DEPTH, which fails the
        range test as the raw reading does); pixel (y, x) is at [y + 1, x + 1]. rays: (H/s, W/s, 3) camera
        rays (z = 1) of the allocation pixels. params: the frame's ``rot_blocks``, ``start_blocks``
        (block = floor(round(p / voxel) / B) = floor(p / block + 0.5 / B)) and the dense side^3 volume's
        corner (cells x-major; samples outside are clamped in). band_m: -trunc, 0, trunc.
        Free space: the allocation pixels whose row and column are multiples of ``carve_stride`` (0:
        none) also sample their ray from the camera every ``carve_step_m`` of depth up to the band
        (depths k step < d - trunc, k = 0, 1, ...), so the blocks it crosses in front of the surface are
        allocated and updated too, and their voxels read observed free (``TsdfCfg.free_space_stride``).
        keys, key_slots: the hash's (capacity,) buffers. volume_stamp: (parts, side^3) int32. slot_stamp:
        (capacity, parts) int32. new_keys: (parts, >= side^3) int64 out; ``state``'s part counters zero
        before; cells beyond the key range are counted at S_PARTS + 2 part + 1 (``BlockHash.insert``'s
        error)."""
        row, run = wp.tid()
        r = first_row + row
        c_first = run * columns_per_run
        prm = params[0]
        stamp = state[S_STAMP]
        num_keys = state[S_NUM_BLOCKS]
        for c in range(c_first, wp.min(c_first + columns_per_run, rays.shape[1])):
            d = depth_pad_m[r * stride_px + 1, c * stride_px + 1]
            if d >= depth_min_m and d <= depth_max_m:
                rx = rays[r, c, 0]
                ry = rays[r, c, 1]
                rz = rays[r, c, 2]
                # the ray's world direction in blocks per metre, once for its 3 samples
                ray_w = wp.vec3(rx * prm.rot_blocks[0, 0] + ry * prm.rot_blocks[1, 0] + rz * prm.rot_blocks[2, 0],
                                rx * prm.rot_blocks[0, 1] + ry * prm.rot_blocks[1, 1] + rz * prm.rot_blocks[2, 1],
                                rx * prm.rot_blocks[0, 2] + ry * prm.rot_blocks[1, 2] + rz * prm.rot_blocks[2, 2])
                for j in range(3):
                    mark_sample(d + band_m[j], ray_w, prm, side, part, stamp, num_keys, volume_stamp, keys,
                                key_slots, slot_stamp, new_keys, state)
                if carve_stride > 0:
                    if r % carve_stride == 0 and c % carve_stride == 0:
                        limit = d + band_m[0]
                        k = int(0)
                        dd = float(0.0)
                        while dd < limit:
                            mark_sample(dd, ray_w, prm, side, part, stamp, num_keys, volume_stamp, keys,
                                        key_slots, slot_stamp, new_keys, state)
                            k += 1
                            dd = float(k) * carve_step_m

    @wp.kernel(enable_backward=False)
    def select_blocks(
        slots_per_run: wp.int32,
        slot_stamp: wp.array2d(dtype=wp.int32),
        slot_coords: wp.array2d(dtype=wp.int64),
        params: wp.array(dtype=FrameParams),
        centre_scale: wp.vec3,
        radius_m: wp.float32,
        truncation_m: wp.float32,
        depth_min_m: wp.float32,
        depth_max_m: wp.float32,
        depth_pad_m: wp.array2d(dtype=wp.float32),
        has_surface: wp.array(dtype=wp.bool),
        selected: wp.array(dtype=wp.int64),
        state: wp.array(dtype=wp.int32),
        mode: wp.int32,
        view_stamp: wp.array(dtype=wp.int32),
    ):
        """The blocks allocated before this frame (slots < ``state[S_NUM_BLOCKS]``) that it updates,
        appended to ``selected`` at ``state[S_SELECTED]`` (ascending on the CPU): blocks stamped by
        ``mark_band_blocks`` (in any part) and blocks holding a surface that the view may clear
        (``TsdfMap._blocks_in_view``, the same float32 operations); the frame's new blocks are updated
        too, but need no selecting. ``has_surface`` of a selected block is cleared (the voxel update sets
        it again). Nothing when ``state[S_SKIP]`` is set. Thread ``tid`` does slots [tid n, (tid + 1) n),
        n = ``slots_per_run`` (1 on CUDA, the capacity on the CPU).

        ``mode`` splits the two tests (SELECT_BOTH, else the CPU's overlapped frame, ``tsdf.launches``):
        SELECT_VIEW keeps only the surface blocks in view and stamps them in ``view_stamp`` (it runs
        while ``mark_band_blocks`` runs, so it must not read the band's stamps); SELECT_BAND, after the
        marking, keeps the band's blocks that SELECT_VIEW did not. ``view_stamp``: (capacity,) int32.

        slot_coords: (capacity, 3) int64 block coordinates. params: the frame's world-to-camera
        ``rot_cw``, ``t_cw``, intrinsics ``k`` and ``radius_px_m``. centre_scale: (0.5, block size, half a
        voxel): a block's centre is (b + 0.5) size - half voxel. radius_m: half a block's diagonal.
        slot_stamp: (capacity, parts) int32. depth_pad_m: (H + 2, W + 2) float32 padded depth, as
        ``mark_band_blocks`` reads it."""
        if state[S_SKIP] != 0:
            return
        first = wp.tid() * slots_per_run
        h = depth_pad_m.shape[0] - 2
        w = depth_pad_m.shape[1] - 2
        stamp = state[S_STAMP]
        prm = params[0]
        rot_cw = prm.rot_cw
        for i in range(first, wp.min(first + slots_per_run, state[S_NUM_BLOCKS])):
            keep = bool(False)
            if mode != SELECT_VIEW:
                for p in range(slot_stamp.shape[1]):
                    if slot_stamp[i, p] == stamp:
                        keep = True
                if mode == SELECT_BAND and view_stamp[i] == stamp:
                    keep = False  # updated with the view's blocks
            if not keep and has_surface[i] and mode != SELECT_BAND:
                bx = (float(slot_coords[i, 0]) + centre_scale[0]) * centre_scale[1] - centre_scale[2]
                by = (float(slot_coords[i, 1]) + centre_scale[0]) * centre_scale[1] - centre_scale[2]
                bz = (float(slot_coords[i, 2]) + centre_scale[0]) * centre_scale[1] - centre_scale[2]
                px = bx * rot_cw[0, 0] + by * rot_cw[0, 1] + bz * rot_cw[0, 2] + prm.t_cw[0]
                py = bx * rot_cw[1, 0] + by * rot_cw[1, 1] + bz * rot_cw[1, 2] + prm.t_cw[1]
                z = bx * rot_cw[2, 0] + by * rot_cw[2, 1] + bz * rot_cw[2, 2] + prm.t_cw[2]
                zc = wp.max(z, 1.0e-3)
                u = int(wp.rint(px / zc * prm.k[0] + prm.k[2]))
                v = int(wp.rint(py / zc * prm.k[1] + prm.k[3]))
                margin = int((1.0 / zc) * prm.radius_px_m)
                near = z + radius_m > depth_min_m and z - radius_m < depth_max_m
                inside = u + margin >= 0 and u - margin < w and v + margin >= 0 and v - margin < h
                if near and inside and z > 0.0:
                    d = depth_pad_m[wp.clamp(v, 0, h - 1) + 1, wp.clamp(u, 0, w - 1) + 1]
                    valid = d >= depth_min_m and d <= depth_max_m
                    keep = not valid or z - radius_m < d + truncation_m
            if keep:
                selected[wp.atomic_add(state, S_SELECTED, 1)] = wp.int64(i)
                has_surface[i] = False
                if mode == SELECT_VIEW:
                    view_stamp[i] = stamp

    @wp.kernel(enable_backward=False)
    def integrate_voxels(
        first_run: wp.int32,
        max_runs: wp.int32,
        stride: wp.int32,
        runs_per_block: wp.int32,
        voxels_per_run: wp.int32,
        selected: wp.array(dtype=wp.int64),
        slot_coords: wp.array2d(dtype=wp.int64),
        block_voxels: wp.int32,
        voxel_size_m: wp.float32,
        params: wp.array(dtype=FrameParams),
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
        dropoff_m: wp.float32,
        dropoff_scale: wp.float32,
        tsdf: wp.array2d(dtype=wp.float32),
        weight: wp.array2d(dtype=wp.float32),
        color: wp.array3d(dtype=wp.uint8),
        updated: wp.array(dtype=wp.bool),
        has_surface: wp.array(dtype=wp.bool),
        state: wp.array(dtype=wp.int32),
    ):
        """The voxel update of the frame's blocks: runs [first_run, first_run + max_runs) of the
        (``state[S_SELECTED]`` + ``state[S_NEW_BLOCKS]``) * ``runs_per_block`` runs, a grid-stride loop
        (thread ``tid`` does runs first_run + tid, + stride, ...; stride = the launch size), so a launch of fixed size (a captured
        graph on CUDA) covers however many blocks the frame has. A run is ``voxels_per_run`` consecutive
        voxels (runs_per_block * voxels_per_run = V = B^3 voxels per block): one voxel on CUDA, a whole
        block on the CPU.

        Block i is slot ``selected[i]`` for i < ``state[S_SELECTED]`` (``select_blocks``' output), else
        the new slot ``state[S_NUM_BLOCKS]`` + i - ``state[S_SELECTED]`` (the frame's new blocks).
        slot_coords: (capacity, 3) int64 block coordinates. params: ``kr``, ``kt`` (the homogeneous
        padded-pixel coordinates of block i's origin o = coords B voxel are kr o + kt, summed as
        ``TsdfMap._project``, and a voxel's are that plus local_px: (3, V) float32 K' R of each local
        offset) and ``with_color``. depth_pad_m: (H + 2, W + 2) float32 the frame's depth (non-finite as
        NO_DEPTH) inside a 1-pixel NO_DEPTH border, read without bounds checks; rgb: (H, W, 3) uint8 the
        frame's colour (read only with colour; it needs no padded copy: only updated voxels read it, and
        their nearest pixel is inside the image, as the border fails the depth range test). tsdf,
        weight: (capacity, V) float32 and color: (capacity, V, 3) uint8, updated in place. updated,
        has_surface: (capacity,) bool set True where a voxel of the block was updated / holds tsdf < 0
        (``select_blocks`` cleared ``has_surface``). dropoff_m: behind the surface by more than this
        (sdf < -dropoff_m) an observation weighs less, linearly down to 0 at -truncation (voxblox's
        weight drop-off; 0: off); dropoff_scale: 1 / (truncation - dropoff_m), a float32 product in both
        paths (torch divides by a scalar as a product with its reciprocal)."""
        num_selected = state[S_SELECTED]
        first_new_slot = state[S_NUM_BLOCKS]
        total_runs = (num_selected + state[S_NEW_BLOCKS]) * runs_per_block
        end = wp.min(first_run + max_runs, total_runs)
        run = first_run + wp.tid()
        prm = params[0]
        kr = prm.kr
        kt = prm.kt
        with_color = prm.with_color
        while run < end:
            i = run // runs_per_block
            lv_first = (run - i * runs_per_block) * voxels_per_run
            slot = wp.int64(first_new_slot + i - num_selected)
            if i < num_selected:
                slot = selected[i]
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
                # off the image lands on the NO_DEPTH border. One reciprocal and two products instead of two
                # divisions (the torch path does the same, so both round alike)
                inv_z = 1.0 / zc
                u = wp.clamp(x * inv_z, 0.0, width_px + 0.75)
                v = wp.clamp(y * inv_z, 0.0, height_px + 0.75)
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
                        if dropoff_m > 0.0 and sdf < -dropoff_m:  # behind the surface: less and less sure
                            w_obs = w_obs * ((sdf + truncation_m) * dropoff_scale)
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
            run += stride


def available() -> bool:
    """Whether Warp is importable (else ``TsdfMap`` falls back to its torch path)."""
    return wp is not None



__all__ = ["KEY_OFFSET", "MAX_STEP", "NO_DEPTH", "available", "integrate_voxels", "mark_band_blocks",
           "select_blocks"]
