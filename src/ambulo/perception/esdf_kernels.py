"""``esdf.edt``'s exact squared EDT as Warp kernels (CPU and CUDA), a thread per grid line.

Why kernels: the windowed torch EDT is 2K + 1 whole-array minima per axis (~240 passes over the grid
at 5 cm voxels and a 2 m maximum distance), each reading and writing the whole grid. The separable
exact transform needs one O(n) sweep per line and axis instead: the first axis (sites to 1-D squared
distance) is a forward and a backward scan for the nearest site; each further axis is the 1-D
squared distance transform of Felzenszwalb & Huttenlocher ("Distance transforms of sampled
functions", Theory of Computing 8, 2012): the lower envelope of the parabolas (q - v)^2 + f(v), built
in one sweep, read off in a second. Warp (``warp-lang``) compiles both kernels for the CPU (LLVM) and
CUDA from the same source; launches go to the device and the current torch stream of the sites
tensor, sharing its memory zero-copy.

Exactness (the torch path's result for every input, bit for bit): every squared distance is an
integer, exact in float32 below 2^24; envelope breakpoints are ratios of integers, compared as cross
products of integers exact in float64 (no division, no rounding). A squared distance above ``cap_sq``
(the largest integer whose float32 square root is <= max_cells) is stored as inf after every axis:
later axes only add to it, so it could never come back within max_cells, and the envelopes skip it
(fewer parabolas where sites are sparse). The last axis writes sqrt(d^2) (correctly rounded, as
torch's), or inf beyond the cap.

Layout: a pass along axis a sees the grid as an (n, P, Q) view (axis a first, the others in order), so
on CUDA (a thread per line) neighbouring threads read neighbouring addresses for every axis but the
contiguous one, which goes first and is the cheap sites scan; the envelope scratch is [k, line], k-major
(coalesced). A Warp CPU launch runs on one thread, so on the CPU each pass is one launch per range of
lines, one range per ``torch.get_num_threads()`` thread (the native call releases the GIL; ranges write
disjoint lines), a Warp thread looping over its range with one scratch column, contiguous and in L1.
Compilation happens once per device on the first launch (~1.6 s on the CPU, longer for CUDA) and is
cached on disk (Warp's kernel cache, ``WARP_CACHE_PATH``).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import torch

try:
    import warp as wp
except ImportError:  # esdf.edt falls back to its torch path
    wp = None

if wp is not None:

    @wp.func
    def _stored_value(d_sq: wp.float64, cap_sq: wp.float64, finish: int):
        """A squared distance as stored: inf beyond the cap; as a distance (sqrt) on the last axis."""
        value = wp.float32(wp.inf)
        if d_sq <= cap_sq:
            value = wp.float32(d_sq)
            if finish != 0:
                value = wp.sqrt(value)
        return value

    @wp.func
    def _store(out: wp.array3d(dtype=wp.float32), i: int, p: int, q: int, d_sq: wp.float64, cap_sq: wp.float64,
               finish: int):
        """Write ``_stored_value``."""
        out[i, p, q] = _stored_value(d_sq, cap_sq, finish)

    @wp.kernel(enable_backward=False)
    def sites_scan(
        first_line: wp.int32,
        lines_per_thread: wp.int32,
        first_column: wp.int32,
        sites: wp.array3d(dtype=wp.bool),
        cap_sq: wp.float64,
        finish: wp.int32,
        out: wp.array3d(dtype=wp.float32),
    ):
        """First axis. sites: (n, P, Q) bool view, the axis first; thread tid does lines [l0, l0 +
        lines_per_thread), l0 = first_line + tid lines_per_thread, line = p Q + q (``first_column``:
        unused, as ``envelope_pass``). out: (n, P, Q) float32 squared distance along the line to its
        nearest site (inf beyond ``cap_sq`` or without a site); the distance itself when ``finish``."""
        n = sites.shape[0]
        line_first = first_line + wp.tid() * lines_per_thread
        for line in range(line_first, wp.min(line_first + lines_per_thread, sites.shape[1] * sites.shape[2])):
            p = line // sites.shape[2]
            q = line - p * sites.shape[2]
            # forward: squared distance to the nearest site at or before i (inf before the first)
            last = int(-1)
            for i in range(n):
                if sites[i, p, q]:
                    last = i
                d_sq = wp.float32(wp.inf)
                if last >= 0:
                    d_sq = wp.float32((i - last) * (i - last))
                out[i, p, q] = d_sq
            # backward: the nearest site at or after i, if nearer
            nxt = int(-1)
            for j in range(n):
                i = n - 1 - j
                if sites[i, p, q]:
                    nxt = i
                d_sq = out[i, p, q]
                if nxt >= 0:
                    d_sq = wp.min(d_sq, wp.float32((nxt - i) * (nxt - i)))
                _store(out, i, p, q, wp.float64(d_sq), cap_sq, finish)

    @wp.kernel(enable_backward=False)
    def envelope_pass(
        first_line: wp.int32,
        lines_per_thread: wp.int32,
        first_column: wp.int32,
        f: wp.array3d(dtype=wp.float32),
        cap_sq: wp.float64,
        finish: wp.int32,
        v: wp.array2d(dtype=wp.int32),
        g: wp.array2d(dtype=wp.float32),
        z_num: wp.array2d(dtype=wp.float64),
        z_den: wp.array2d(dtype=wp.int32),
    ):
        """A further axis, in place: f(i) <- min_j (i - j)^2 + f(j) along each line (Felzenszwalb &
        Huttenlocher). f: (n, P, Q) float32 view, the axis first, finite (<= cap_sq) or inf; lines as
        ``sites_scan``'s, written as there. Scratch of column c = first_column + tid, [k, c], for the
        k-th parabola of the envelope: v, g: (n, C) int32 its vertex and float32 f there; z_num: (n, C)
        float64, z_den: (n, C) int32 where it starts to be the lowest, z = z_num / z_den (z_den > 0;
        -1 / 0 stands for -inf, 1 / 0 for +inf). Breakpoints are compared as cross products, exact in
        float64, rather than divided: a division is the loop's slowest operation."""
        n = f.shape[0]
        c = first_column + wp.tid()
        line_first = first_line + wp.tid() * lines_per_thread
        for line in range(line_first, wp.min(line_first + lines_per_thread, f.shape[1] * f.shape[2])):
            p = line // f.shape[2]
            q = line - p * f.shape[2]
            # 1. the lower envelope of the finite parabolas f(v) + (x - v)^2; the top one (k) in registers:
            # its vertex, f(v) + v^2, and its breakpoint
            k = int(-1)
            vk = int(0)
            big_fk = wp.float64(0.0)
            num_k = wp.float64(-1.0)
            den_k = int(0)
            f_next = f[0, p, q]
            for i in range(n):
                # f(i + 1) is loaded an iteration ahead: on CUDA its latency overlaps this one's work
                fi = f_next
                if i + 1 < n:
                    f_next = f[i + 1, p, q]
                if wp.float64(fi) <= cap_sq:
                    big_fi = wp.float64(fi) + wp.float64(i * i)
                    num = wp.float64(-1.0)
                    den = int(0)
                    while k >= 0:
                        # parabola i gets below parabola vk at num / den; vk is nowhere the lowest (drop
                        # it) unless that is after where vk starts to be (num / den > num_k / den_k)
                        num = big_fi - big_fk
                        den = 2 * (i - vk)
                        if num * wp.float64(den_k) > num_k * wp.float64(den):
                            break
                        k -= 1
                        if k >= 0:
                            vk = v[k, c]
                            big_fk = wp.float64(g[k, c]) + wp.float64(vk * vk)
                            num_k = z_num[k, c]
                            den_k = z_den[k, c]
                    if k < 0:  # the lowest everywhere so far: it starts at -inf
                        num = wp.float64(-1.0)
                        den = 0
                    k += 1
                    v[k, c] = i
                    g[k, c] = fi
                    z_num[k, c] = num
                    z_den[k, c] = den
                    vk = i
                    big_fk = big_fi
                    num_k = num
                    den_k = den
            # 2. read it off (over f: the envelope holds what it needs): the parabola lowest at i is
            # the last one starting at or before i
            if k < 0:
                for i in range(n):
                    f[i, p, q] = wp.float32(wp.inf)
            else:
                top = k
                j = int(0)
                vj = v[0, c]
                fj = wp.float64(g[0, c])
                num_next = wp.float64(1.0)  # where parabola j + 1 starts: +inf after the top one
                den_next = int(0)
                if top > 0:
                    num_next = z_num[1, c]
                    den_next = z_den[1, c]
                for i in range(n):
                    while num_next < wp.float64(i * den_next):
                        j += 1
                        vj = v[j, c]
                        fj = wp.float64(g[j, c])
                        num_next = wp.float64(1.0)
                        den_next = 0
                        if j < top:
                            num_next = z_num[j + 1, c]
                            den_next = z_den[j + 1, c]
                    _store(f, i, p, q, wp.float64((i - vj) * (i - vj)) + fj, cap_sq, finish)


    @wp.kernel(enable_backward=False)
    def window_sites(sites: wp.array3d(dtype=wp.bool), k_max: wp.int32, cap_sq: wp.float64, finish: wp.int32,
                     out: wp.array3d(dtype=wp.float32)):
        """The first axis, a thread per cell (``exact_edt``'s "window" layout): the squared distance along
        the line to the nearest site within ``k_max`` cells (k^2 <= cap_sq <=> |k| <= k_max), searched
        outwards. sites, out: (n, P, Q) views, the axis first."""
        i, p, q = wp.tid()
        n = sites.shape[0]
        best = wp.float64(wp.inf)
        if sites[i, p, q]:
            best = wp.float64(0.0)
        k = int(1)
        while k <= k_max and best > wp.float64(0.0):
            if (i >= k and sites[i - k, p, q]) or (i + k < n and sites[i + k, p, q]):
                best = wp.float64(k * k)
                k = k_max
            k += 1
        _store(out, i, p, q, best, cap_sq, finish)

    @wp.kernel(enable_backward=False)
    def window_pass(f: wp.array3d(dtype=wp.float32), k_max: wp.int32, cap_sq: wp.float64, finish: wp.int32,
                    clamp_cells: wp.float32, scale: wp.float32, out: wp.array3d(dtype=wp.float32)):
        """A further axis, a thread per cell: min over |k| <= k_max of f[i + k] + k^2 (a nearer minimum
        ends the search: k^2 only grows), the exact 1-D transform for every value <= cap_sq (a parabola
        from further than k_max adds more than the cap). f, out: (n, P, Q) views (distinct arrays). The
        last axis (``finish``) writes min(distance, clamp_cells) * scale (``esdf_from_grid``'s clamp and
        unit in the same float32 operations; inf and 1 for the bare distance)."""
        i, p, q = wp.tid()
        n = f.shape[0]
        best = wp.float64(f[i, p, q])
        k = int(1)
        while k <= k_max and wp.float64(k * k) < best:
            kk = wp.float64(k * k)
            if i >= k:
                best = wp.min(best, wp.float64(f[i - k, p, q]) + kk)
            if i + k < n:
                best = wp.min(best, wp.float64(f[i + k, p, q]) + kk)
            k += 1
        value = _stored_value(best, cap_sq, finish)
        if finish != 0:
            value = wp.min(value, clamp_cells) * scale
        out[i, p, q] = value

    @wp.kernel(enable_backward=False)
    def classify_voxels(tsdf: wp.array(dtype=wp.float32), weight: wp.array(dtype=wp.float32), min_weight: wp.float32,
                        occupied: wp.array(dtype=wp.bool), observed: wp.array(dtype=wp.bool)):
        """``DenseGrid.occupied`` and ``observed`` in one pass (flat views)."""
        i = wp.tid()
        seen = weight[i] >= min_weight
        observed[i] = seen
        occupied[i] = seen and tsdf[i] < 0.0


def available() -> bool:
    """Whether Warp is importable (else ``esdf.edt`` uses its torch path)."""
    return wp is not None


def cap_squared(max_cells: float, shape: tuple[int, ...]) -> int:
    """The largest integer squared distance whose float32 square root is <= max_cells (the torch
    path's ``dist <= max_cells`` test), bounded by the grid's diagonal; -1 when none is."""
    diagonal_sq = sum((n - 1) ** 2 for n in shape)
    limit = np.float32(max_cells)
    if not limit >= 0:  # negative or nan: nothing is near enough
        return -1
    t = diagonal_sq + 1 if float(limit) ** 2 > diagonal_sq else int(float(limit) ** 2)
    while t >= 0 and np.sqrt(np.float32(t)) > limit:
        t -= 1
    while t <= diagonal_sq and np.sqrt(np.float32(t + 1)) <= limit:
        t += 1
    return min(t, diagonal_sq)


_pool: ThreadPoolExecutor | None = None
"""Worker threads of split CPU launches (created on first use)."""
_loaded_on: set[str] = set()
"""Devices this module's kernels are loaded on (by ``exact_edt``)."""


def _view(t: torch.Tensor, device):
    """A zero-copy Warp array over a (possibly permuted) torch tensor on Warp ``device``: the bare
    constructor, a fraction of ``wp.from_torch``'s host time. It does not keep ``t`` alive: callers
    hold their tensors until the launches are queued (on CUDA in torch's stream, so the caching
    allocator reuses their memory only for work queued after them)."""
    return wp.array(ptr=t.data_ptr(), dtype=wp.dtype_from_torch(t.dtype), shape=tuple(t.shape),
                    strides=tuple(st * t.element_size() for st in t.stride()), device=device, copy=False)


def _line_view(t: torch.Tensor, axis: int) -> torch.Tensor:
    """(n, P, Q) view of an up-to-3-D grid: ``axis`` first, the others in order, size-1 axes added."""
    others = [a for a in range(t.ndim) if a != axis]
    view = t.permute(axis, *others)
    while view.ndim < 3:
        view = view.unsqueeze(1)
    return view


CUDA_BLOCK_DIM = 64
"""Threads per CUDA block. A pass has only ~10^4 lines (threads), each a long serial loop: small
blocks spread them over every SM (8400 lines = 132 blocks, one per H100 SM, where Warp's default 256
would fill 33)."""


def _columns(lines: int, per_line: bool) -> int:
    """Scratch columns, one per Warp thread: a thread per line (CUDA), or a thread per range of lines,
    one range per torch thread (the CPU; a range is worth a hand-off from 64 lines)."""
    return lines if per_line else max(1, min(torch.get_num_threads(), lines // 64))


def _launch(kernel, lines: int, inputs: list, device, stream, per_line: bool) -> None:
    """``kernel`` over ``lines`` lines. ``per_line`` (CUDA): one launch, a thread per line and scratch
    column, in torch's stream. Else (the CPU): one single-thread launch per range of lines, range r on
    its own thread (the native call releases the GIL) with scratch column r."""
    if per_line:
        wp.launch(kernel, dim=lines, inputs=[0, 1, 0, *inputs], device=device, stream=stream,
                  block_dim=CUDA_BLOCK_DIM)
        return
    parts = _columns(lines, per_line)
    bounds = [lines * r // parts for r in range(parts + 1)]

    def run(r: int) -> None:
        wp.launch(kernel, dim=1, inputs=[bounds[r], bounds[r + 1] - bounds[r], r, *inputs], device=device)

    if parts == 1:
        run(0)
        return
    global _pool
    if _pool is None or _pool._max_workers < parts - 1:
        _pool = ThreadPoolExecutor(max_workers=parts - 1, thread_name_prefix="ambulo-esdf")
    futures = [_pool.submit(run, r) for r in range(1, parts)]
    run(0)
    for fut in futures:
        fut.result()  # waits, and re-raises a worker's error


def exact_edt(sites: torch.Tensor, max_cells: float, thread_per_line: bool | None = None,
              window: bool | None = None) -> torch.Tensor:
    """``esdf.edt`` (sites: 1-, 2- or 3-D bool; float32 distance in cells, inf beyond max_cells) on the
    sites' device: ``sites_scan`` along the last (contiguous) axis, then ``envelope_pass`` in place
    along the others, last to first. ``thread_per_line``: that CUDA launch layout; True on the CPU runs
    it there, one slow single-thread launch, so tests cover it without a GPU.

    ``window`` (the CUDA default): a thread per *cell* instead, each searching the cells within
    max_cells along the axis (``window_sites``, ``window_pass``; the same result). A thread per line
    leaves a GPU nearly idle (~10^4 lines of a 1 M-cell map: one 64-thread block per H100 SM, each
    thread a serial sweep waiting on memory), while a thread per cell fills it and reads neighbouring
    addresses; its O(max_cells) work per cell ends early near a surface. On the CPU, where a Warp
    launch runs on one thread, the O(n)-per-line sweeps do less work, so they stay the default."""
    if not 1 <= sites.ndim <= 3:
        raise ValueError(f"exact_edt takes a 1-, 2- or 3-D grid, got {sites.ndim}-D: use esdf.edt_torch")
    sites = sites.to(torch.bool).contiguous()
    out = torch.empty(sites.shape, dtype=torch.float32, device=sites.device)
    if sites.numel() == 0:
        return out
    wp.init()  # no-op once initialised
    device = wp.device_from_torch(sites.device)
    stream = wp.stream_from_torch(sites.device) if device.is_cuda else None
    if device.is_cuda if window is None else window:
        return _window_edt(sites, max_cells, out, device, stream)
    per_line = device.is_cuda if thread_per_line is None else bool(thread_per_line)
    if not per_line and device.alias not in _loaded_on:
        # before the threaded launches: their first launches would each compile the module
        wp.load_module(sites_scan.module, device=device)
        _loaded_on.add(device.alias)
    cap_sq = float(cap_squared(max_cells, tuple(sites.shape)))
    axes = list(range(sites.ndim - 1, -1, -1))
    first = _line_view(sites, axes[0])
    _launch(sites_scan, first.shape[1] * first.shape[2],
            [_view(first, device), cap_sq, int(sites.ndim == 1), _view(_line_view(out, axes[0]), device)],
            device, stream, per_line)
    if sites.ndim == 1:
        return out
    # envelope scratch shared by the further axes: [k, column], k < the longest of them
    longest = max(sites.shape[a] for a in axes[1:])
    columns = max(_columns(sites.numel() // sites.shape[a], per_line) for a in axes[1:])
    if per_line:  # neighbouring lines (threads) in neighbouring columns: coalesced on CUDA
        shape, transpose = (longest, columns), False
    else:  # one range's envelope contiguous (and in L1)
        shape, transpose = (columns, longest), True
    scratch = [torch.empty(shape, dtype=dtype, device=sites.device)
               for dtype in (torch.int32, torch.float32, torch.float64, torch.int32)]
    scratch_views = [_view(t.t() if transpose else t, device) for t in scratch]
    for axis in axes[1:]:
        f = _line_view(out, axis)
        _launch(envelope_pass, f.shape[1] * f.shape[2], [_view(f, device), cap_sq, int(axis == axes[-1]),
                                                         *scratch_views], device, stream, per_line)
    return out


def _window_edt(sites: torch.Tensor, max_cells: float, out: torch.Tensor, device, stream,
                clamp_cells: float = float("inf"), scale: float = 1.0) -> torch.Tensor:
    """``exact_edt``'s thread-per-cell layout: the axes last to first, ping-ponging between ``out`` and a
    scratch grid so that the last pass writes ``out`` (min(distance, clamp_cells) * scale; a 1-D grid,
    whose only pass is the sites scan, is not clamped or scaled)."""
    cap_sq = cap_squared(max_cells, tuple(sites.shape))
    k_max = int(np.floor(np.sqrt(max(cap_sq, 0)))) if cap_sq >= 0 else -1
    axes = list(range(sites.ndim - 1, -1, -1))
    bufs = [out, torch.empty_like(out)] if len(axes) > 1 else [out]
    # the pass writing buffer b: the last pass writes out
    order = [bufs[(len(axes) - 1 - j) % len(bufs)] for j in range(len(axes))]
    src = None
    for j, axis in enumerate(axes):
        dst = _line_view(order[j], axis)
        finish = int(j == len(axes) - 1)
        if j == 0:
            kernel, inputs = window_sites, [_view(_line_view(sites, axis), device), k_max, float(cap_sq), finish]
        else:
            kernel, inputs = window_pass, [_view(_line_view(src, axis), device), k_max, float(cap_sq), finish,
                                           float(clamp_cells), float(scale)]
        wp.launch(kernel, dim=tuple(dst.shape), inputs=[*inputs, _view(dst, device)], device=device, stream=stream)
        src = order[j]
    return out


def occupancy_esdf(tsdf: torch.Tensor, weight: torch.Tensor, min_weight: float, max_cells: int,
                   voxel_size_m: float) -> tuple[torch.Tensor, torch.Tensor]:
    """``esdf.esdf_from_grid``'s unsigned field on CUDA in 4 launches: the occupied and observed masks
    in one pass, then the window EDT whose last pass clamps to max_cells and scales to metres. Returns
    (distance_m, observed), both (X, Y, Z), the same values as the general path. It runs on the CPU
    too (one thread per launch: slower than the general path there), so CI tests it."""
    wp.init()
    device = wp.device_from_torch(tsdf.device)
    stream = wp.stream_from_torch(tsdf.device) if device.is_cuda else None
    occupied = torch.empty(tsdf.shape, dtype=torch.bool, device=tsdf.device)
    observed = torch.empty_like(occupied)
    wp.launch(classify_voxels, dim=tsdf.numel(), device=device, stream=stream, inputs=[
        _view(tsdf.reshape(-1), device), _view(weight.reshape(-1), device), float(min_weight),
        _view(occupied.view(-1), device), _view(observed.view(-1), device)])
    out = torch.empty(tsdf.shape, dtype=torch.float32, device=tsdf.device)
    _window_edt(occupied, max_cells, out, device, stream, clamp_cells=float(np.float32(max_cells)),
                scale=float(np.float32(voxel_size_m)))
    return out, observed


__all__ = ["available", "cap_squared", "exact_edt", "occupancy_esdf"]
