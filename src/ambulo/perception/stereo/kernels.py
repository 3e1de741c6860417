"""Semi-global aggregation (``stereo.sgm.aggregate``) as fused Warp kernels (CPU and CUDA).

Why kernels: the torch version scans each direction one image line at a time, ~9 small ops per
step, ~11 700 launches per 500x741 pair; on a GPU that is launch-bound (36.7 ms on an H100 even
replayed as a CUDA graph) while the arithmetic is ~2 GB of memory traffic. Here one launch (CUDA)
or two concurrent ones (CPU) cover every path.

Work split: by path *line*, a start pixel whose predecessor along the direction lies outside the
image and every pixel after it. A line is sequential (a pixel needs the previous one's minimum over
all disparities), so the parallelism is lines x disparities: 2 (H + W) + 4 (H + W - 1) lines for 8
paths (7 442 at 500x741).

* CUDA (``sgm_lines_tiled``): a block per line, its lanes splitting the disparities (64 lanes for
  D = 64), ~476 k threads in all. They exchange the previous pixel's path costs through ``scratch``
  (global memory, but a block's own 2 x D floats, so it stays in L1): a lane reads L(q, d - 1 .. d
  + 1), writes L(p, d) into the other row, and the block-wide ``tile_min`` of L(p, .) (every lane
  needs min L(p) for N(p) = L(p) - min L(p)) is also the barrier between one step's writes and the
  next step's reads: Warp's code for it (``tile.h``) runs ``__syncthreads`` after every lane's loads
  and stores of the step whatever the block size (storing the result in a shared tile for all lanes
  to read syncs before and after, on top of the reduction's own syncs across warps). Storing L and
  subtracting the minimum on read keeps it to one reduction per step. The directions run
  concurrently and add into the output atomically. Not yet timed on a GPU when written (none at
  hand): ``benchmarks/stereo.py --device cuda`` times it against the torch aggregation.
* CPU (``sgm_lines``): a thread per line looping over the disparities. A Warp CPU launch runs its
  threads one after the other on one OS thread, so the paths are split into two mirrored halves
  (a direction and its opposite do alike work and memory access) launched from two OS threads
  into two outputs, summed on the way out. No tile ops here: Warp's CPU tile arena is one static
  buffer (``tile.h``: "ideally this would be thread_local"), so tile kernels must not run on two
  CPU threads at once; the tiled kernel runs on the CPU only in the tests (one launch at a time).

Exactness: each path cost takes the torch version's float32 operations in its order (N = L - min,
then min(N, p2), N(d +- 1) + p1, then + C: ``path_cost``), so per path the values are bit-identical.
The paths are summed in another order (atomics, two outputs); census costs and penalties are
integers and the sums stay far below 2^24, where float32 addition is exact, so the total is
bit-identical too (non-integer costs would differ by float32 rounding).

Memory: the kernels take the cost and the output as (H, W, D), disparity fastest, so a pixel's
disparities are one contiguous run (coalesced on CUDA; on the CPU the (D, H, W) layout ran 3.4x
slower); ``aggregate_warp`` transposes the (D, H, W) volumes of ``stereo.sgm`` on the way in and
out (one copy each).

Compilation happens once per device (and CUDA block size) on the first launch, ~1.5 s on the CPU,
and is cached on disk (Warp's kernel cache).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import torch

try:
    import warp as wp
except ImportError:  # stereo.sgm falls back to its torch aggregation
    wp = None

CUDA_MAX_LANES = 128
"""Most lanes per line on CUDA; beyond that a lane takes several disparities (D > 128)."""

HALF_PATHS = {4: ((0, 1), (1, 0)), 8: ((0, 1), (1, 0), (1, 1), (1, -1))}
"""(dy, dx) steps of the first half of the directions (the kernels' ``path_step``); the second
half are their opposites in the same order, so that a half is a mirror of the other: as much work
and alike memory access, which the CPU splits between two threads."""

_pool: ThreadPoolExecutor | None = None
"""The thread that launches the second half of the paths on the CPU (made on first use)."""

_streams: dict = {}
"""Warp's handles of torch CUDA streams, by raw handle (``wp.stream_from_torch`` registers the
stream with Warp each time it is called)."""


def available() -> bool:
    """Whether Warp is importable (else ``sgm_disparity`` aggregates in torch)."""
    return wp is not None


def directions(paths: int) -> tuple[tuple[int, int], ...]:
    """(dy, dx) of the ``paths`` directions in the kernels' order: HALF_PATHS, then their opposites."""
    half = HALF_PATHS[paths]
    return half + tuple((-dy, -dx) for dy, dx in half)


def num_lines(dy: int, dx: int, height: int, width: int) -> int:
    """Lines of direction (dy, dx) over an image: one per pixel whose predecessor is outside it."""
    from_first_row = width if dy != 0 else 0
    from_first_column = (height - 1 if dy != 0 else height) if dx != 0 else 0
    return from_first_row + from_first_column


if wp is not None:

    @wp.func
    def path_step(k: int, paths: int):
        """(dy, dx) of direction k of ``paths`` (``directions``)."""
        half = paths // 2
        sign = 1
        if k >= half:
            sign = -1
            k -= half
        step = wp.vec2i(1, -1)
        if k == 0:
            step = wp.vec2i(0, 1)
        elif k == 1:
            step = wp.vec2i(1, 0)
        elif k == 2:
            step = wp.vec2i(1, 1)
        return step * sign

    @wp.func
    def lines_of(dy: int, dx: int, height: int, width: int):
        """``num_lines`` in a kernel."""
        count = int(0)
        if dy != 0:
            count = width
        if dx != 0:
            if dy != 0:
                count += height - 1
            else:
                count += height
        return count

    @wp.func
    def line_origin(line: int, paths: int, height: int, width: int):
        """(dy, dx, y, x): the direction of ``line`` (lines are numbered direction by direction, in
        ``directions`` order) and its first pixel. Of a direction's lines, 0 .. W - 1 start on the
        row the path enters by (when it moves along y), the others on the column it enters by."""
        k = int(0)
        step = path_step(0, paths)
        count = lines_of(step[0], step[1], height, width)
        while line >= count and k + 1 < paths:
            line -= count
            k += 1
            step = path_step(k, paths)
            count = lines_of(step[0], step[1], height, width)
        dy = step[0]
        dx = step[1]
        y = line
        x = int(0)
        if dx < 0:
            x = width - 1
        if dy != 0:
            y0 = int(0)
            if dy < 0:
                y0 = height - 1
            if line < width:
                y = y0
                x = line
            else:  # the corner pixel starts a row line already: the column's lines begin one in
                y = y0 + dy * (line - width + 1)
        return wp.vec4i(dy, dx, y, x)

    @wp.func
    def lesser(a: wp.float32, b: wp.float32):
        """min(a, b) of values that are never NaN: ``wp.min`` handles NaN in ~4 more instructions
        (the CPU kernel ran ~8 % faster without)."""
        return a if a < b else b

    @wp.func
    def path_cost(n_below: wp.float32, n_same: wp.float32, n_above: wp.float32, d: int, depth: int,
                  p1: wp.float32, p2: wp.float32, c: wp.float32):
        """L(p, d) from N(q, d - 1 .. d + 1) and C(p, d), in the torch version's order of float32
        operations: clamp at p2, then the neighbours' + p1 (none past the ends of the range), + C."""
        best = lesser(n_same, p2)
        if d > 0:
            best = lesser(best, n_below + p1)
        if d < depth - 1:
            best = lesser(best, n_above + p1)
        return best + c

    @wp.kernel(enable_backward=False)
    def sgm_lines(
        cost: wp.array3d(dtype=wp.float32),
        paths: int,
        first_line: int,
        p1: wp.float32,
        p2: wp.float32,
        scratch: wp.array2d(dtype=wp.float32),
        out: wp.array3d(dtype=wp.float32),
    ):
        """CPU: a thread per line, over all disparities; adds L of the line's pixels into ``out``.

        cost: (H, W, D) C(y, x, d); out: (H, W, D), += L(p, d) (plain adds: a CPU launch runs its
        threads one after the other, and each of the concurrent launches has its own ``out``).
        scratch: (lines, D) L of the line's previous pixel, overwritten in place: L(p, d) is written
        after N(q, d + 1) is read, and N(q, d - 1), N(q, d) are kept from the iterations before.
        Thread t does line first_line + t of ``paths`` directions (``line_origin``).
        """
        line = first_line + wp.tid()
        height = cost.shape[0]
        width = cost.shape[1]
        depth = cost.shape[2]
        origin = line_origin(line, paths, height, width)
        dy = origin[0]
        dx = origin[1]
        y = origin[2]
        x = origin[3]
        low_prev = float(0.0)  # min_k L(q, k)
        started = int(0)  # 0 at the first pixel: N(q) = 0 before the path enters the image
        while y >= 0 and y < height and x >= 0 and x < width:
            low = float(wp.inf)
            n_below = float(0.0)
            n_same = float(0.0)
            if started != 0:
                n_same = scratch[line, 0] - low_prev
            for d in range(depth):
                n_above = float(0.0)
                if started != 0 and d < depth - 1:
                    n_above = scratch[line, d + 1] - low_prev
                path = path_cost(n_below, n_same, n_above, d, depth, p1, p2, cost[y, x, d])
                scratch[line, d] = path
                out[y, x, d] = out[y, x, d] + path
                low = lesser(low, path)
                n_below = n_same
                n_same = n_above
            low_prev = low
            started = 1
            y += dy
            x += dx

    @wp.kernel(enable_backward=False)
    def sgm_lines_tiled(
        cost: wp.array3d(dtype=wp.float32),
        paths: int,
        p1: wp.float32,
        p2: wp.float32,
        scratch: wp.array3d(dtype=wp.float32),
        out: wp.array3d(dtype=wp.float32),
    ):
        """CUDA: a block per line (``launch_tiled``), lane l taking disparities l, l + lanes, ...

        cost: (H, W, D) C(y, x, d); out: (H, W, D), zero before the launch, += L(p, d) atomically
        (every direction runs in this launch). scratch: (lines, 2, D) per line L of the previous
        pixel and of this one (the rows swap per step, so no lane overwrites what another still reads).
        """
        line, lane = wp.tid()
        lanes = wp.block_dim()
        height = cost.shape[0]
        width = cost.shape[1]
        depth = cost.shape[2]
        origin = line_origin(line, paths, height, width)
        dy = origin[0]
        dx = origin[1]
        y = origin[2]
        x = origin[3]
        prev = int(0)  # scratch row holding L(q) of the previous pixel q
        low_prev = float(0.0)
        started = int(0)
        while y >= 0 and y < height and x >= 0 and x < width:
            low = float(wp.inf)
            d = lane
            while d < depth:
                n_below = float(0.0)
                n_same = float(0.0)
                n_above = float(0.0)
                if started != 0:
                    n_same = scratch[line, prev, d] - low_prev
                    if d > 0:
                        n_below = scratch[line, prev, d - 1] - low_prev
                    if d < depth - 1:
                        n_above = scratch[line, prev, d + 1] - low_prev
                path = path_cost(n_below, n_same, n_above, d, depth, p1, p2, cost[y, x, d])
                scratch[line, 1 - prev, d] = path
                wp.atomic_add(out, y, x, d, path)
                low = lesser(low, path)
                d += lanes
            # every lane gets here (the pixel loop is the block's): the reduction is also the
            # barrier that orders this step's scratch writes before the next step's reads, and
            # this step's reads before the next step's writes to the same row
            low_prev = wp.tile_min(wp.tile(low))[0]
            prev = 1 - prev
            started = 1
            y += dy
            x += dx


def warp_stream(device: torch.device):
    """Warp's handle of torch's current stream on CUDA ``device``: the launch is ordered with the
    torch ops around it and, inside a torch CUDA graph capture, captured with them."""
    ts = torch.cuda.current_stream(device)
    stream = _streams.get(ts.cuda_stream)
    if stream is None:
        stream = _streams[ts.cuda_stream] = wp.stream_from_torch(ts)
    return stream


def cuda_lanes(num_disparities: int) -> int:
    """Lanes per line on CUDA: one per disparity in whole warps (64 for D = 64; Warp's block
    reductions need whole warps), at most CUDA_MAX_LANES: each warp more adds to every step's
    reduction across warps (an untuned guess, no GPU at hand)."""
    return min(CUDA_MAX_LANES, 32 * -(-num_disparities // 32))


def _check_cost(cost) -> None:
    if not isinstance(cost, torch.Tensor) or cost.dtype != torch.float32 or cost.ndim != 3:
        what = f"{cost.dtype} {tuple(cost.shape)}" if isinstance(cost, torch.Tensor) else type(cost).__name__
        raise ValueError(f"aggregate_warp needs a (D, H, W) float32 cost tensor, not {what}")
    if cost.device.type not in ("cpu", "cuda"):
        raise ValueError(f"aggregate_warp runs on the CPU or CUDA, not {cost.device}: pass aggregation='torch'")


def _launch_tiled(cost_hwd: torch.Tensor, paths: int, p1: float, p2: float, lines: int, lanes: int) -> torch.Tensor:
    """(H, W, D) sum of the path costs, one ``sgm_lines_tiled`` launch (on torch's current stream on CUDA)."""
    device = cost_hwd.device
    out_hwd = torch.zeros_like(cost_hwd)
    # per call from torch's allocator (its cache on CUDA, the graph's pool during a capture): no
    # buffer is shared between calls or graphs; every entry is written before it is read
    scratch = torch.empty((lines, 2, cost_hwd.shape[2]), dtype=torch.float32, device=device)
    wp.launch_tiled(sgm_lines_tiled, dim=lines, block_dim=lanes, device=wp.device_from_torch(device),
                    stream=warp_stream(device) if device.type == "cuda" else None,
                    inputs=[wp.from_torch(cost_hwd), paths, p1, p2, wp.from_torch(scratch), wp.from_torch(out_hwd)])
    return out_hwd


def _launch_cpu(cost_hwd: torch.Tensor, paths: int, p1: float, p2: float,
                half_lines: int) -> list[torch.Tensor]:
    """(H, W, D) path cost sums of the two mirrored halves of the paths (``sgm_lines``), launched
    from two threads when torch may use two; one sum when it may use one."""
    out = [torch.zeros_like(cost_hwd) for _ in range(2 if torch.get_num_threads() > 1 else 1)]
    scratch = torch.empty((2 * half_lines, cost_hwd.shape[2]), dtype=torch.float32)

    def launch(first_line: int, count: int, out_hwd: torch.Tensor) -> None:
        wp.launch(sgm_lines, dim=count, device="cpu", inputs=[
            wp.from_torch(cost_hwd), paths, first_line, p1, p2, wp.from_torch(scratch), wp.from_torch(out_hwd)])

    sgm_lines.module.load(wp.get_device("cpu"))  # once, not by both threads at the first call
    if len(out) == 1:
        launch(0, 2 * half_lines, out[0])
        return out
    global _pool
    if _pool is None:
        _pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="ambulo-sgm")
    second = _pool.submit(launch, half_lines, half_lines, out[1])  # Warp's native launch releases the GIL
    launch(0, half_lines, out[0])
    second.result()
    return out


def aggregate_warp(cost: torch.Tensor, cfg, lanes: int | None = None) -> torch.Tensor:
    """(D, H, W) float32 sum of the semi-global path costs over ``cfg.paths`` directions, equal to
    ``stereo.sgm.aggregate(cost, cfg)`` (bit for bit for integer costs), on ``cost``'s device.

    cost: (D, H, W) float32 matching cost on the CPU or CUDA; cfg: an ``SgmCfg`` (paths, p1, p2).
    lanes: None for the device's kernel (CPU: a thread per line; CUDA: ``sgm_lines_tiled`` with
    ``cuda_lanes``); a number runs ``sgm_lines_tiled`` with that many lanes, on the CPU only with
    ``wp.config.enable_cpu_blocks`` (cooperative fibers, slow: the tests' check of the CUDA kernel)
    and never concurrently with another CPU tile kernel. Memory: cost and output transposed, (H,
    W, D) each (and a second output on the CPU), plus 2 x D floats per line.
    """
    if wp is None:
        raise ImportError("aggregate_warp needs warp-lang: pip install 'ambulo[perception]'")
    _check_cost(cost)
    if cfg.paths not in (4, 8):
        raise ValueError(f"paths must be 4 or 8, not {cfg.paths}")
    if lanes is not None and not (0 < lanes <= 1024 and (cost.device.type == "cpu" or lanes % 32 == 0)):
        # Warp's block reductions use full-warp masks: a partial warp on CUDA is undefined behaviour
        raise ValueError(f"lanes must be 1 .. 1024, and a multiple of 32 on CUDA, not {lanes}")
    if cost.numel() == 0:
        return torch.zeros_like(cost)
    wp.init()  # no-op once initialised
    _, height, width = cost.shape
    half_lines = sum(num_lines(dy, dx, height, width) for dy, dx in HALF_PATHS[cfg.paths])
    cost_hwd = cost.permute(1, 2, 0).contiguous()
    p1, p2 = float(cfg.p1), float(cfg.p2)
    if cost.device.type == "cpu" and lanes is None:
        out = _launch_cpu(cost_hwd, cfg.paths, p1, p2, half_lines)
    else:
        lanes = lanes or cuda_lanes(cost.shape[0])
        out = [_launch_tiled(cost_hwd, cfg.paths, p1, p2, 2 * half_lines, lanes)]
    for other in out[1:]:
        out[0] += other  # in (H, W, D) first: a transposing add took twice an add and a transposing copy
    return out[0].permute(2, 0, 1).contiguous()


__all__ = ["CUDA_MAX_LANES", "HALF_PATHS", "aggregate_warp", "available", "cuda_lanes", "directions", "num_lines",
           "warp_stream"]
