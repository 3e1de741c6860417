"""The recorded Warp launches of ``TsdfMap.integrate`` (``IntegrateLaunches``) and how they are split
over threads on the CPU; the kernels themselves are ``tsdf.kernels``.

Separate from the kernels because this is host-side Python (argument packing, thread hand-off) that
changes for launch overhead, while the kernels change for the arithmetic they share with the torch path.

Host overhead: each launch is recorded once (``wp.Launch``, ``IntegrateLaunches``) and replayed with
only the changed arguments set, instead of a ``wp.launch`` packing ~25 arguments (~80 us of Python on
the CPU); the frame's matrices and counters live in the ``params`` / ``state`` arrays the kernels read,
written on the CPU through numpy views (no torch op). Torch ops per frame: the padded depth copy; in
frames that allocate blocks none more on the CPU (the hash merges in numpy on its buffers), and the
storage's growth when its capacity doubles. On CUDA these launches serve only frames too deep for the
dense volume: ``TsdfMap`` replays a captured graph of the same kernels instead (``tsdf.graph``).

CPU: a Warp CPU launch runs its threads one after the other on one OS thread (so a kernel thread does a
whole block or image row: ``tsdf.kernels``), and ``IntegrateLaunches.update_voxels`` splits the blocks into
ranges that up to ``torch.get_num_threads()`` threads take in turn (the native call releases the GIL; ranges
write disjoint voxels, the per-block flags are only ever set True). ``mark_band_blocks`` can be split only by
giving each range its own outputs (``PARTS``; off by default, measured no faster on 2 cores). Apart from the
padded depth copy, no torch op in ``integrate``'s Warp path touches more than a few thousand elements
(a larger one wakes torch's OpenMP pool, whose threads may spin on the cores these launches run on;
scoping that copy to one thread measured no better).
"""

from __future__ import annotations

import threading
from collections import deque
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import torch

from .kernels import (
    S_NEW_BLOCKS,
    S_NUM_BLOCKS,
    S_PARTS,
    S_SELECTED,
    S_STAMP,
    SELECT_BAND,
    SELECT_BOTH,
    SELECT_VIEW,
    state_size,
    wp,
)

if wp is not None:  # without Warp, TsdfMap takes its torch path and never makes these launches
    from .kernels import FrameParams, integrate_voxels, mark_band_blocks, select_blocks

PARTS = 1
"""Row ranges of ``mark_band_blocks`` run concurrently on the CPU (read when a map is made), each with its
own stamp volume, key list, counters and ``slot_stamp`` column; CUDA uses one. 1: on 2 cores, 2 parts
measured no faster (2.93-2.99 vs 2.98-3.07 ms/frame at 640x480): the hand-off to a second thread and
back (~0.1 ms) costs what it saves of the ~0.3 ms kernel."""

_pool: ThreadPoolExecutor | None = None
"""Worker threads of split CPU launches (created on first use)."""


def _view(t: torch.Tensor):
    """A zero-copy Warp array over a torch tensor."""
    if t.device.type == "cpu":  # the bare constructor: half the time of wp.from_torch (~15 us)
        return wp.array(ptr=t.data_ptr(), dtype=wp.dtype_from_torch(t.dtype), shape=tuple(t.shape),
                        strides=tuple(st * t.element_size() for st in t.stride()), device="cpu", copy=False)
    return wp.from_torch(t)


def _vec3(v) -> wp.vec3:
    return wp.vec3.from_buffer_copy(np.ascontiguousarray(v, dtype=np.float32))


class _Recorded:
    """One kernel launch recorded once (``wp.launch(..., record_cmd=True)``) and replayed with
    ``wp.Launch.launch``: per frame only what changed is set (~1 us each) instead of packing all ~25
    arguments (a ``wp.launch`` took ~80 us of Python on the CPU). A tensor argument is re-viewed only
    when another tensor object is passed (the storage's or the hash's buffers after their capacity grew), a
    scalar only when its value changed; the bound tensor is kept, so its memory is not reused while
    bound. Vector / matrix values are always set (they change every frame)."""

    def __init__(self, kernel, device, dim, values: dict):
        labels = [a.label for a in kernel.adj.args]
        self._index = {name: i for i, name in enumerate(labels)}
        self._bound = {name: v for name, v in values.items() if isinstance(v, (torch.Tensor, int, float, wp.array))}
        self.launch = wp.launch(kernel, dim=dim, device=device, record_cmd=True, inputs=[
            _view(v) if isinstance(v, torch.Tensor) else v for v in (values[name] for name in labels)])
        self._dim = dim

    def set(self, dim, values: dict) -> wp.Launch:
        """Set the launch size and the given arguments (by name); returns the launch."""
        if dim != self._dim:
            self.launch.set_dim(dim)
            self._dim = dim
        bound, launch, index = self._bound, self.launch, self._index
        for name, v in values.items():
            old = bound.get(name, bound)
            if old is v:
                continue
            if isinstance(v, torch.Tensor):
                bound[name] = v
                v = _view(v)
            elif isinstance(v, wp.array):
                bound[name] = v
            elif isinstance(v, (int, float)):
                if old == v:
                    continue
                bound[name] = v
            launch.set_param_at_index(index[name], v)
        return launch

    def follow(self, leader: _Recorded, dim, own: dict) -> wp.Launch:
        """CPU only: take all of ``leader``'s arguments, then set ``own`` (this range's first row / run
        and size): a copy of the list of packed arguments instead of setting each (a CPU launch reads
        them when it runs; ``set_param_at_index`` replaces an entry, never changes it in place)."""
        launch = self.launch
        launch.params[1:] = leader.launch.params[1:]
        if dim != self._dim:
            launch.set_dim(dim)
            self._dim = dim
        for name, v in own.items():
            launch.set_param_at_index(self._index[name], v)
        return launch


def _run_concurrently(launches: list) -> None:
    """Run CPU ``wp.Launch``es on up to len(launches) threads (the caller's and pool workers'; Warp's
    native call releases the GIL), taken in turn: a thread the OS does not schedule soon does not hold
    the others up (the caller waits only for launches already taken)."""
    if len(launches) == 1:
        launches[0].launch()
        return
    state = {"next": 0, "running": 0, "error": None}
    done = threading.Condition()

    def work() -> None:
        while True:
            with done:
                c = state["next"]
                if c >= len(launches):
                    return
                state["next"] += 1
                state["running"] += 1
            try:
                launches[c].launch()
            except BaseException as e:  # re-raised by the calling thread
                state["error"] = e
                raise
            finally:
                with done:
                    state["running"] -= 1
                    done.notify_all()

    workers = min(torch.get_num_threads(), len(launches)) - 1
    for _ in range(workers):
        _pool_for(workers).submit(work)
    work()
    with done:
        done.wait_for(lambda: state["running"] == 0)
    if state["error"] is not None:
        raise state["error"]


def _pool_for(workers: int) -> ThreadPoolExecutor:
    global _pool
    if _pool is None or _pool._max_workers < workers:
        _pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="ambulo-tsdf")
    return _pool


class _WorkQueue:
    """CPU launches that threads take in turn while more are being added (``IntegrateLaunches.overlapped``)."""

    def __init__(self):
        self._cv = threading.Condition()
        self._tasks: deque = deque()
        self._closed = False
        self._busy = 0
        self.error: BaseException | None = None
        self.view_selected = threading.Event()
        """Set once the pool thread selected the surface blocks in view (or failed)."""

    def push(self, launches: list) -> None:
        with self._cv:
            self._tasks.extend(launches)
            self._cv.notify_all()

    def close(self) -> None:
        """No more launches come: ``work`` returns once the queue is empty."""
        with self._cv:
            self._closed = True
            self._cv.notify_all()

    def _run(self, task) -> None:
        try:
            task.launch()
        except BaseException as e:  # re-raised by the calling thread (``overlapped``)
            self.error = e
        finally:
            with self._cv:
                self._busy -= 1
                self._cv.notify_all()

    def work(self) -> None:
        """Take launches until the queue is closed and empty (a pool thread)."""
        while True:
            with self._cv:
                while not self._tasks and not self._closed:
                    self._cv.wait()
                if not self._tasks:
                    return
                task = self._tasks.popleft()
                self._busy += 1
            self._run(task)

    def drain(self) -> None:
        """Take launches until none is queued or running (the calling thread helps)."""
        while True:
            with self._cv:
                if self._tasks:
                    task = self._tasks.popleft()
                    self._busy += 1
                elif self._busy == 0:
                    return
                else:
                    self._cv.wait()
                    continue
            self._run(task)


class IntegrateLaunches:
    """The Warp launches of one ``TsdfMap``'s ``integrate`` on its device, recorded on first use, and
    the small buffers they share: ``state`` (counters, stamp, block counts: ``tsdf.kernels.S_*``),
    ``params`` (the frame's matrices) and ``local_px``.

    Launches go to torch's current stream on CUDA (ordered with the torch ops around them). On the CPU
    ``mark_band_blocks`` runs as ``parts`` concurrent row ranges and ``integrate_voxels`` as up to
    2 ``torch.get_num_threads()`` block ranges taken in turn by that many threads (ranges write disjoint
    voxels; the per-block flags are only ever set True). On CUDA ``TsdfMap`` replays these kernels as one
    captured graph (``tsdf.graph``) and uses the launches here only where its dense volume is too big."""

    def __init__(self, device: torch.device, block_voxels: int):
        wp.init()  # no-op once initialised
        device = torch.empty(0, device=device).device  # with its index ("cuda" -> "cuda:0"), as Warp needs
        self.wp_device = wp.device_from_torch(device)
        self.is_cuda = self.wp_device.is_cuda
        self.parts = 1 if self.is_cuda else PARTS
        """Parts of ``mark_band_blocks`` (the rows of its outputs ``volume_stamp``, ``new_keys``, the
        columns of ``slot_stamp``)."""
        self.state = torch.zeros(state_size(self.parts), dtype=torch.int32, device=device)
        """(S_PARTS + 2 parts,) int32 the kernels' counters and the frame's stamp and block counts."""
        self._state_host = None if self.is_cuda else self.state.numpy()
        """The CPU state as a numpy view: set and read without a torch op."""
        self.params = wp.zeros(1, dtype=FrameParams, device=self.wp_device)
        """The frame's ``FrameParams`` (one element), read by every kernel."""
        self._params_staging = wp.zeros(1, dtype=FrameParams, device="cpu", pinned=self.is_cuda) if self.is_cuda \
            else self.params
        self.params_host = self._params_staging.numpy()
        """The params' host memory as a numpy structured array (on CUDA a pinned copy, uploaded by
        ``upload``)."""
        self.local_px = torch.zeros((3, block_voxels ** 3), dtype=torch.float32, device=device)
        """(3, B^3) float32 the frame's K' R of each local voxel offset (``integrate_voxels``)."""
        self._local_px_staging = (torch.empty_like(self.local_px, device="cpu", pin_memory=True) if self.is_cuda
                                  else self.local_px)
        """Host memory of the offsets: on CUDA a pinned staging copy uploaded asynchronously (a pageable
        ``copy_`` waits for the stream: a host sync), on the CPU ``local_px`` itself."""
        self._local_px_host = self._local_px_staging.numpy()
        self.no_rgb = torch.zeros((1, 1, 3), dtype=torch.uint8, device=device)
        self._streams: dict = {}
        self._mark: dict = {}
        self._select: dict = {}
        self._select_view: dict = {}
        self._voxels: dict = {}
        self._voxels_view: dict = {}

    def stream(self):
        """Warp's handle of torch's current stream (cached by the stream's handle; None on the CPU)."""
        if not self.is_cuda:
            return None
        ts = torch.cuda.current_stream(self.wp_device.ordinal)
        stream = self._streams.get(ts.cuda_stream)
        if stream is None:
            stream = self._streams[ts.cuda_stream] = wp.stream_from_torch(ts)
        return stream

    def set_frame(self, g, corner_blocks: np.ndarray, radius_px_m: float, with_color: bool) -> None:
        """Write the frame's ``FrameParams`` and local offsets (``tsdf.frame._FrameGeometry`` ``g``) to host
        memory; on CUDA ``upload`` sends them. On CUDA the staging memory is rewritten by the next call,
        so the stream must be waited for in between (``TsdfMap`` reads the state at the end of a frame)."""
        p = self.params_host
        p["rot_blocks"][0] = g.rot_blocks
        p["start_blocks"][0] = g.start_blocks
        p["corner_blocks"][0] = corner_blocks
        p["corner_index"][0] = corner_blocks
        p["rot_cw"][0] = g.rot_cw
        p["t_cw"][0] = g.t_cw
        p["k"][0] = (g.k[0, 0], g.k[1, 1], g.k[0, 2], g.k[1, 2])
        p["radius_px_m"][0] = radius_px_m
        p["kr"][0] = g.kr
        p["kt"][0] = g.kt
        p["with_color"][0] = int(with_color)
        self._local_px_host[...] = g.local_px

    def upload(self) -> None:
        """CUDA: copy the frame's params and offsets from pinned memory on the current stream (async)."""
        if self.is_cuda:
            wp.copy(self.params, self._params_staging, stream=self.stream())
            self.local_px.copy_(self._local_px_staging, non_blocking=True)

    def begin_host_frame(self, stamp: int, num_blocks: int) -> None:
        """Eager path: zero the counters, set the stamp and the blocks allocated so far."""
        if self.is_cuda:
            values = torch.zeros(self.state.shape[0], dtype=torch.int32)
            values[S_STAMP], values[S_NUM_BLOCKS] = stamp, num_blocks
            self.state.copy_(values)
            return
        st = self._state_host
        st.fill(0)
        st[S_STAMP], st[S_NUM_BLOCKS] = stamp, num_blocks

    def read_state(self) -> list[int]:
        """The state on the host: on CUDA a device-to-host copy, which waits for the launches so far."""
        return self.state.tolist() if self.is_cuda else self._state_host.tolist()

    def set_new_blocks(self, count: int) -> None:
        """Eager path: the new blocks the voxel update covers (after the host allocated them)."""
        if self.is_cuda:
            self.state[S_NEW_BLOCKS] = count
        else:
            self._state_host[S_NEW_BLOCKS] = count

    def part_counts(self, st: list[int]) -> tuple[list[int], list[int]]:
        """From a read ``state``: each part's new keys and cells beyond the key range."""
        return st[S_PARTS::2], st[S_PARTS + 1::2]

    def mark(self, *, band_m, **values) -> None:
        """Run ``mark_band_blocks`` (``values``: its other arguments by name, tensors included)."""
        rows, columns = values["rays"].shape[:2]
        values.update(band_m=_vec3(band_m), params=self.params, state=self.state)
        stream = self.stream()
        if self.is_cuda:
            self._recorded(self._mark, 0, mark_band_blocks, (rows, columns), values, first_row=0, part=0,
                           columns_per_run=1).launch(stream=stream)
            return
        parts = min(self.parts, torch.get_num_threads(), rows)
        bounds = [rows * p // parts for p in range(parts + 1)]
        _run_concurrently(self._split(self._mark, mark_band_blocks, values, [
            ((bounds[p + 1] - bounds[p], 1), {"first_row": bounds[p], "part": p, "columns_per_run": columns})
            for p in range(parts)]))

    def select(self, *, num_old: int, centre_scale, mode: int = SELECT_BOTH, cache: dict | None = None,
               **values) -> None:
        """Run ``select_blocks`` over slots [0, num_old) (``mode``: which of its tests)."""
        if num_old == 0:
            return
        values.update(centre_scale=_vec3(centre_scale), params=self.params, state=self.state, mode=mode)
        capacity = values["has_surface"].shape[0]
        dim, per_run = (num_old, 1) if self.is_cuda else (1, capacity)  # CPU: one thread does all (ascending output)
        self._recorded(self._select if cache is None else cache, 0, select_blocks, dim, values,
                       slots_per_run=per_run).launch(stream=self.stream())

    def overlapped(self, *, num_old: int, mark: dict, select: dict, allocate, update) -> None:
        """The CPU frame with the band's marking overlapped: a pool thread selects the surface blocks in
        view (``SELECT_VIEW``, which reads no band stamp) and starts updating them while this thread marks
        the band (``mark_band_blocks``, single-threaded: ~0.3 ms of a ~2.8 ms frame at 640x480, during which
        the second core used to idle); this thread then selects the band's other blocks (``SELECT_BAND``),
        allocates the new ones (``allocate(state, drain)``: the host merge; ``drain`` waits for the queued
        updates, needed before the storage grows) and queues their updates, which both threads take in
        turn. The same blocks are updated as by ``SELECT_BOTH``, each once. ``update()`` gives
        ``integrate_voxels``' arguments (``voxel_values``), read again after ``allocate``.

        Only when no marked cell can fall beyond the key range (the caller checks the dense volume's
        corners): the view's blocks are updated before the marking ends, so a frame the marking would
        refuse must not start."""
        queue = _WorkQueue()
        n_vox = self.local_px.shape[1]

        def view_blocks() -> None:  # on a pool thread
            try:
                self.select(num_old=num_old, mode=SELECT_VIEW, cache=self._select_view, **dict(select))
                n_view = int(self._state_host[S_SELECTED])
                if n_view:
                    queue.push(self._chunks(self._voxels_view, update(), 0, n_view, n_vox))
            except BaseException as e:  # re-raised by the calling thread
                queue.error = e
                queue.close()
            finally:
                queue.view_selected.set()
            queue.work()

        _pool_for(1).submit(view_blocks)
        try:
            self.mark(**mark)
            queue.view_selected.wait()
            if queue.error is None:
                n_view = int(self._state_host[S_SELECTED])
                self.select(num_old=num_old, mode=SELECT_BAND, **dict(select))
                new = allocate(self.read_state(), queue.drain)
                self.set_new_blocks(new)
                total = int(self._state_host[S_SELECTED]) + new
                if total > n_view:
                    queue.push(self._chunks(self._voxels, update(), n_view, total, n_vox))
        finally:
            queue.close()
            queue.drain()
        if queue.error is not None:
            raise queue.error

    def _chunks(self, cache: dict, values: dict, first: int, end: int, n_vox: int) -> list:
        """CPU ``integrate_voxels`` launches over blocks [first, end): 2 per torch thread (one when few)."""
        blocks = end - first
        chunks = 1 if blocks < 64 else 2 * max(1, torch.get_num_threads())
        bounds = [first + blocks * c // chunks for c in range(chunks + 1)]
        return self._split(cache, integrate_voxels, values, [
            (bounds[c + 1] - bounds[c], {"first_run": bounds[c], "max_runs": bounds[c + 1] - bounds[c],
                                         "stride": bounds[c + 1] - bounds[c], "runs_per_block": 1,
                                         "voxels_per_run": n_vox})
            for c in range(chunks) if bounds[c + 1] > bounds[c]])

    def update_voxels(self, *, num_blocks: int, rgb: torch.Tensor | None, **values) -> None:
        """Run ``integrate_voxels`` over ``num_blocks`` blocks (the selected ones, then the new ones).
        ``rgb`` None: no colour."""
        if num_blocks == 0:
            return
        n_vox = self.local_px.shape[1]
        values = voxel_values(self, rgb, **values)
        if self.is_cuda:  # a thread per voxel
            dim = num_blocks * n_vox
            self._recorded(self._voxels, 0, integrate_voxels, dim, values, first_run=0, max_runs=dim, stride=dim,
                           runs_per_block=n_vox, voxels_per_run=1).launch(stream=self.stream())
            return
        # CPU: a thread per block, the blocks in 2 parts contiguous ranges that ``parts`` threads take in turn
        # (a thread the OS schedules late holds no one up); one launch when too few blocks to pay for the hand-off
        parts = max(1, min(torch.get_num_threads(), num_blocks // 32))
        chunks = 1 if parts == 1 else 2 * parts
        bounds = [num_blocks * c // chunks for c in range(chunks + 1)]
        _run_concurrently(self._split(self._voxels, integrate_voxels, values, [
            (bounds[c + 1] - bounds[c], {"first_run": bounds[c], "max_runs": bounds[c + 1] - bounds[c],
                                         "stride": bounds[c + 1] - bounds[c], "runs_per_block": 1,
                                         "voxels_per_run": n_vox})
            for c in range(chunks)]))

    def _recorded(self, cache: dict, key, kernel, dim, values: dict, **more) -> wp.Launch:
        """The recorded launch ``cache[key]`` of ``kernel`` with these arguments (recorded on first use)."""
        values.update(more)
        rec = cache.get(key)
        if rec is None:
            rec = cache[key] = _Recorded(kernel, self.wp_device, dim, values)
        return rec.set(dim, values)

    def _split(self, cache: dict, kernel, values: dict, ranges: list) -> list:
        """CPU launches of ``kernel`` over ranges (dim, own arguments): the first takes ``values``, the
        others copy its packed arguments (``_Recorded.follow``)."""
        (dim, own), *rest = ranges
        launches = [self._recorded(cache, 0, kernel, dim, values, **own)]
        leader = cache[0]
        for i, (dim, own) in enumerate(rest, 1):
            rec = cache.get(i)
            if rec is None:
                rec = cache[i] = _Recorded(kernel, self.wp_device, dim, dict(values, **own))
            launches.append(rec.follow(leader, dim, own))
        return launches


def dropoff_scale(truncation_m: float, dropoff_m: float) -> float:
    """1 / (truncation - drop-off depth) in float32 (``integrate_voxels``' ``dropoff_scale``; both paths)."""
    return float(np.float32(1.0) / (np.float32(truncation_m) - np.float32(dropoff_m)))


def voxel_values(launches: IntegrateLaunches, rgb: torch.Tensor | None, *, weight_ref_depth_m: float | None,
                 clear_free_space: bool, truncation_m: float, dropoff_m: float, **values) -> dict:
    """``integrate_voxels``' arguments from ``TsdfMap``'s settings and buffers (shared with ``tsdf.graph``)."""
    values.update(rgb=launches.no_rgb if rgb is None else rgb, weight_ref_depth_m=float(weight_ref_depth_m or 0.0),
                  clear_free_space=int(clear_free_space), truncation_m=float(truncation_m), dropoff_m=float(dropoff_m),
                  dropoff_scale=dropoff_scale(truncation_m, dropoff_m),
                  inv_truncation=float(1.0 / truncation_m), local_px=launches.local_px, params=launches.params,
                  state=launches.state)
    return values


__all__ = ["PARTS", "IntegrateLaunches", "voxel_values"]
