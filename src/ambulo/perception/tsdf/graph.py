"""``TsdfMap.integrate`` as one captured graph: every step of a frame, the hash's growth included, runs
on the device without the host reading anything in between.

Why: on a GPU the eager path (``tsdf.launches``) spent most of a frame on the host. Its kernels kept an
H100 busy ~0.08 ms of a 0.85 ms frame; the rest was ~14 launches, the torch ops merging new keys
into the hash, and one read of the counters in the middle of the frame. That read tells the host how
many blocks are new, which it needs for the merge and the voxel update's launch size. Here those
sizes stay on the device: every kernel reads them from ``state`` (``tsdf.kernels.S_*``). Launches
have fixed sizes (``integrate_voxels`` loops grid-stride over whatever the frame has). The new keys
are merged into the sorted key array by the kernels below. So the frame is captured once, as a CUDA
graph, and replayed; per frame the host uploads the frame's matrices, copies the depth into the
graph's buffer and, at the end, reads the state once.

A frame whose new blocks would not fit the storage changes nothing (``plan_frame`` sets
``S_SKIP``; the selection, merge and update then do nothing). The host sees that in the state it
reads at the end, grows the storage, captures again and replays the same frame. A frame with a block
beyond the key range changes nothing either, and the host raises. Slots are handed out in key order
(the rank of each new key), as ``BlockHash.append`` does, so slot numbering is deterministic, and
independent of the order in which GPU threads found the keys.

On the CPU Warp records the same launches into an operation stream replayed in C++ (its "APIC"
capture), which the tests use to check the graph against the eager path. The eager path stays the
CPU default: it splits the voxel update over threads, which a CPU replay does not.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from . import kernels
from .kernels import (
    S_NEW_BLOCKS,
    S_NUM_BLOCKS,
    S_PARTS,
    S_SKIP,
    S_STAMP,
    SKIP_FULL,
    SKIP_OUT_OF_RANGE,
    wp,
)
from .launches import IntegrateLaunches, voxel_values

if wp is not None:
    from .kernels import count_below, integrate_voxels, mark_band_blocks, select_blocks

    @wp.kernel(enable_backward=False)
    def begin_frame(state: wp.array(dtype=wp.int32)):
        """Zero the counters and advance the stamp (so a replayed frame marks afresh)."""
        for i in range(state.shape[0]):
            if i != S_STAMP and i != S_NUM_BLOCKS:
                state[i] = 0
        state[S_STAMP] = state[S_STAMP] + 1

    @wp.kernel(enable_backward=False)
    def plan_frame(state: wp.array(dtype=wp.int32), capacity: wp.int32):
        """After marking: skip the frame if a block is beyond the key range or the new blocks do not fit;
        else the update covers the new blocks."""
        new = state[S_PARTS]
        if state[S_PARTS + 1] > 0:
            state[S_SKIP] = SKIP_OUT_OF_RANGE
        elif state[S_NUM_BLOCKS] + new > capacity:
            state[S_SKIP] = SKIP_FULL
        else:
            state[S_NEW_BLOCKS] = new

    @wp.kernel(enable_backward=False)
    def rank_new_keys(new_keys: wp.array2d(dtype=wp.int64), state: wp.array(dtype=wp.int32),
                      sorted_new: wp.array(dtype=wp.int64)):
        """Sort the frame's m = ``state[S_NEW_BLOCKS]`` distinct new keys into ``sorted_new`` by rank: key
        j goes to the number of new keys below it (O(m) per key; m is the blocks a frame adds, hundreds
        once the first frames have built the map, and a sort of a fixed-size buffer would cost more)."""
        j = wp.tid()
        m = state[S_NEW_BLOCKS]
        if j < m:
            key = new_keys[0, j]
            rank = int(0)
            for i in range(m):
                if new_keys[0, i] < key:
                    rank += 1
            sorted_new[rank] = key

    @wp.kernel(enable_backward=False)
    def merge_keys(keys: wp.array(dtype=wp.int64), key_slots: wp.array(dtype=wp.int64),
                   sorted_new: wp.array(dtype=wp.int64), state: wp.array(dtype=wp.int32),
                   merged_keys: wp.array(dtype=wp.int64), merged_slots: wp.array(dtype=wp.int64),
                   slot_coords: wp.array2d(dtype=wp.int64)):
        """Merge the n old sorted keys and the m sorted new ones into ``merged_*``: an entry's place is its
        index plus the count of the other run's keys below it (the runs share no key). Threads [0,
        capacity) place the old keys, the rest the new ones, which take slots n, n + 1, ... in key order
        and get their block coordinates (``block_hash.decode``)."""
        t = wp.tid()
        n = state[S_NUM_BLOCKS]
        m = state[S_NEW_BLOCKS]
        capacity = keys.shape[0]
        if t < capacity:
            if t < n:
                pos = t + count_below(sorted_new, m, keys[t])
                merged_keys[pos] = keys[t]
                merged_slots[pos] = key_slots[t]
        else:
            j = t - capacity
            if j < m:
                key = sorted_new[j]
                pos = j + count_below(keys, n, key)
                merged_keys[pos] = key
                merged_slots[pos] = wp.int64(n + j)
                mask = wp.int64((1 << 20) - 1)
                slot_coords[n + j, 0] = ((key >> wp.int64(40)) & mask) - wp.int64(kernels.KEY_OFFSET)
                slot_coords[n + j, 1] = ((key >> wp.int64(20)) & mask) - wp.int64(kernels.KEY_OFFSET)
                slot_coords[n + j, 2] = (key & mask) - wp.int64(kernels.KEY_OFFSET)

    @wp.kernel(enable_backward=False)
    def take_merged(merged_keys: wp.array(dtype=wp.int64), merged_slots: wp.array(dtype=wp.int64),
                    state: wp.array(dtype=wp.int32), keys: wp.array(dtype=wp.int64),
                    key_slots: wp.array(dtype=wp.int64)):
        """Copy the merged keys back into the hash's buffers (after the voxel update, which reads none)."""
        i = wp.tid()
        if state[S_NEW_BLOCKS] > 0 and i < state[S_NUM_BLOCKS] + state[S_NEW_BLOCKS]:
            keys[i] = merged_keys[i]
            key_slots[i] = merged_slots[i]

    @wp.kernel(enable_backward=False)
    def end_frame(state: wp.array(dtype=wp.int32)):
        """The new blocks are allocated."""
        state[S_NUM_BLOCKS] = state[S_NUM_BLOCKS] + state[S_NEW_BLOCKS]


UPDATE_THREADS = 1 << 18
"""Threads of the captured voxel update on CUDA (grid-stride over the frame's voxels: ~2 waves of an
H100's 132 SMs x 2048 threads; a frame updates ~0.1-1 M voxels)."""


@dataclass(frozen=True)
class GraphKey:
    """What a captured graph binds: it is captured again when any of it changes."""

    capacity: int
    buffers: tuple
    """``id``s of the bound tensors (the storage and the hash's buffers change object when they grow)."""
    image: tuple[int, int]
    side: int


class IntegrateGraph:
    """One ``TsdfMap``'s frame as a captured Warp graph (CUDA graph; an operation stream on the CPU),
    sharing ``IntegrateLaunches``' state, params and offsets."""

    def __init__(self, launches: IntegrateLaunches):
        self.launches = launches
        self._graph = None
        self._key: GraphKey | None = None
        self._merged: tuple[torch.Tensor, torch.Tensor] | None = None
        self._sorted_new: torch.Tensor | None = None
        self.rgb: torch.Tensor | None = None
        """(H, W, 3) uint8 the graph's colour buffer (the frame's colour is copied in)."""

    def bind(self, m, buf, cfg) -> None:
        """Make the graph for map ``m`` (a ``TsdfMap``) with frame buffers ``buf``: captured again when
        what it binds changed (the storage grew, another image size)."""
        key = GraphKey(capacity=m.hash.capacity, image=buf.shape, side=2 * buf.r_blocks + 1,
                       buffers=tuple(id(t) for t in (m.tsdf, m.hash.key_buffer, buf.depth, buf.new_keys)))
        if key != self._key:
            self._capture(m, buf, cfg, key)

    def launch(self) -> None:
        """Replay the bound graph on torch's current stream (after the frame's depth, colour and params
        are in its buffers)."""
        wp.capture_launch(self._graph, stream=self.launches.stream())

    def _capture(self, m, buf, cfg, key: GraphKey) -> None:
        launches = self.launches
        device = launches.wp_device
        capacity, (h, w) = key.capacity, key.image
        if self._merged is None or self._merged[0].shape[0] != capacity:
            self._merged = (torch.empty(capacity, dtype=torch.int64, device=m.device),
                            torch.empty(capacity, dtype=torch.int64, device=m.device))
        max_new = buf.new_keys.shape[1]
        if self._sorted_new is None or self._sorted_new.shape[0] != max_new:
            self._sorted_new = torch.empty(max_new, dtype=torch.int64, device=m.device)
        if self.rgb is None or tuple(self.rgb.shape[:2]) != (h, w):
            self.rgb = torch.zeros((h, w, 3), dtype=torch.uint8, device=m.device)
        # kernels load before the capture (a module load inside one needs a CUDA 12.3+ driver)
        for kernel in (begin_frame, mark_band_blocks, plan_frame, select_blocks, rank_new_keys, merge_keys,
                       integrate_voxels, take_merged, end_frame):
            kernel.module.load(device)
        view = wp.from_torch
        state, params = view(launches.state), launches.params
        keys, slots, coords = (view(t) for t in (m.hash.key_buffer, m.hash.key_slot_buffer, m.hash.slot_coord_buffer))
        merged_keys, merged_slots = (view(t) for t in self._merged)
        sorted_new, depth, new_keys = view(self._sorted_new), view(buf.depth), view(buf.new_keys)
        rows, columns = buf.rays.shape[:2]
        n_vox = cfg.block_voxels ** 3
        radius = m.block_radius_m
        # a capture needs a stream of its own (torch's default stream is the legacy one, which can not
        # capture); the graph is replayed on torch's current stream
        stream = wp.Stream(device) if launches.is_cuda else None
        with wp.ScopedCapture(device=device, stream=stream) as capture:
            def launch(kernel, dim, inputs):
                wp.launch(kernel, dim=dim, inputs=inputs, device=device, stream=stream)

            launch(begin_frame, 1, [state])
            launch(mark_band_blocks, (rows, columns), [
                0, 0, 1, depth, cfg.allocation_stride, view(buf.rays), params,
                wp.vec3(-cfg.truncation_m, 0.0, cfg.truncation_m), cfg.carve_stride, cfg.free_space_step_m, key.side,
                cfg.depth_min_m, cfg.depth_max_m,
                view(buf.volume_stamp), keys, slots, view(m._slot_stamp), new_keys, state])
            launch(plan_frame, 1, [state, capacity])
            launch(select_blocks, capacity, [
                1, view(m._slot_stamp), coords, params,
                wp.vec3(0.5, cfg.block_size_m, 0.5 * cfg.voxel_size_m), radius, cfg.truncation_m,
                cfg.depth_min_m, cfg.depth_max_m, depth, view(m.has_surface), view(m._selected), state,
                kernels.SELECT_BOTH, view(m._view_stamp)])
            launch(rank_new_keys, max_new, [new_keys, state, sorted_new])
            launch(merge_keys, capacity + max_new, [keys, slots, sorted_new, state, merged_keys, merged_slots,
                                                    coords])
            values = voxel_values(
                launches, self.rgb, weight_ref_depth_m=cfg.weight_ref_depth_m, clear_free_space=cfg.clear_free_space,
                truncation_m=cfg.truncation_m, dropoff_m=cfg.dropoff_m, selected=m._selected, slot_coords=m.hash.slot_coord_buffer,
                block_voxels=cfg.block_voxels, voxel_size_m=cfg.voxel_size_m, depth_pad_m=buf.depth,
                depth_min_m=cfg.depth_min_m, depth_max_m=cfg.depth_max_m, max_weight=cfg.max_weight,
                tsdf=m.tsdf, weight=m.weight, color=m.color, updated=m.updated, has_surface=m.has_surface)
            threads, per_run = (UPDATE_THREADS, 1) if launches.is_cuda else (capacity, n_vox)
            values.update(first_run=0, max_runs=capacity * n_vox, stride=threads,
                          runs_per_block=n_vox // per_run, voxels_per_run=per_run)
            labels = [a.label for a in integrate_voxels.adj.args]
            launch(integrate_voxels, threads, [
                view(v) if isinstance(v, torch.Tensor) else v for v in (values[name] for name in labels)])
            launch(take_merged, capacity, [merged_keys, merged_slots, state, keys, slots])
            launch(end_frame, 1, [state])
        self._graph, self._key = capture.graph, key


def check_state(st: list[int]) -> int:
    """The skip reason in a read state (0: the frame was integrated); raises for a block beyond the
    key range."""
    if st[S_SKIP] == SKIP_OUT_OF_RANGE:
        from .block_hash import raise_out_of_range  # only on bad input

        raise_out_of_range()
    return st[S_SKIP]


__all__ = ["SKIP_FULL", "UPDATE_THREADS", "IntegrateGraph", "check_state"]
