"""Stereo disparity in torch (the same code on the CPU and CUDA): census cost, semi-global
aggregation along 4 or 8 paths (Hirschmüller 2008), winner-take-all with a uniqueness test, an
equiangular fit for sub-pixel disparity, a left-right consistency check and a 3x3 median.
Invalid pixels are nan. The aggregation runs as fused Warp kernels where Warp imports
(``stereo.kernels``, ``SgmCfg.aggregation``), else as torch ops (``aggregate``): the same numbers.
``CudaGraphSgm`` replays the whole matcher as one CUDA graph; ``stereo_frame`` turns a rectified
pair into an ``RgbdFrame`` for the mapper.

Every cost is an integer held in float32 (census Hamming distances and integer penalties), so the
aggregation is exact and the CPU and CUDA give the same disparities.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from ambulo.utils.checks import InvalidValueError, check_int, check_positive
from ambulo.utils.validate import Checked

from ..frames import RgbdFrame

AGGREGATIONS = ("auto", "torch", "warp")
"""Values of ``SgmCfg.aggregation``."""


@dataclass(kw_only=True)
class SgmCfg(Checked):
    """Semi-global matching settings. The penalties are the usual ones for a 9x7 census, not fitted
    to one pair: on the Middlebury Motorcycle pair that scikit-image ships (500x741, disparities
    7-60 px) bad 2.0 stays within 4.8-5.3 % for p1 5-10, p2 60-120 (``benchmarks/stereo.py``)."""

    num_disparities: int = 64
    """Search range 0 .. num_disparities - 1, px."""
    census_rows: int = 7
    census_cols: int = 9
    """Census window, px: odd sides, rows x cols <= 63 so that its bits fit one int64."""
    p1: int = 7
    """Penalty for a 1 px disparity step between neighbours along a path (census cost units)."""
    p2: int = 86
    """Penalty for a larger step (a depth edge)."""
    paths: int = 8
    """4 (horizontal and vertical) or 8 (and the diagonals)."""
    uniqueness_ratio: float = 0.05
    """Reject a pixel unless every disparity more than 1 px from the winner costs at least
    (1 + this) times the winner's cost (OpenCV's uniquenessRatio / 100)."""
    max_lr_diff_px: int = 1
    """Reject a pixel whose right-image disparity differs by more than this (occlusions, mismatches)."""
    median_size: int = 3
    """Median filter on the disparity (0 or 1: off; else odd), px."""
    aggregation: str = "auto"
    """Who sums the path costs: "warp" (fused Warp kernels, ``stereo.kernels.aggregate_warp``),
    "torch" (``aggregate``: per scan step a few torch ops, ~11 700 launches per 500x741 pair on a
    GPU) or "auto": Warp where it imports, on CUDA and on the CPU, else torch. The result is the
    same to the bit. On the CPU Warp was the faster (the aggregation alone at 500x741, D = 64,
    ``torch.set_num_threads(2)``, 2-core Xeon VM, medians of 4: 8 paths 560 ms vs torch 738 ms,
    4 paths 357 vs 671 ms; one thread, 8 paths: 1045 vs 1328 ms; a second run agreed within 7 %),
    after a one-off ~1.5 s kernel compile cached on disk."""

    def __post_init__(self):
        check_int("SgmCfg.num_disparities", self.num_disparities, "pass a search range of 2 px or more, e.g. 64",
                  minimum=2)
        if self.paths not in (4, 8):
            raise InvalidValueError("SgmCfg.paths", self.paths, "SGM scans 4 or 8 directions", "pass 4 or 8")
        check_int("SgmCfg.p1", self.p1, "pass a census-cost penalty >= 0, e.g. 7", minimum=0)
        check_int("SgmCfg.p2", self.p2, f"pass a penalty >= p1 ({self.p1}), e.g. 86", minimum=self.p1)
        check_positive("SgmCfg.uniqueness_ratio", self.uniqueness_ratio, "pass a ratio >= 0, e.g. 0.05",
                       allow_zero=True)
        check_int("SgmCfg.max_lr_diff_px", self.max_lr_diff_px, "pass a tolerance >= 0 px, e.g. 1", minimum=0)
        size = check_int("SgmCfg.median_size", self.median_size, "pass 0 (off) or an odd size, e.g. 3", minimum=0)
        if size > 1 and size % 2 == 0:
            raise InvalidValueError("SgmCfg.median_size", size, "a median window needs an odd side",
                                    "pass 0 (off) or an odd size, e.g. 3")
        if self.aggregation not in AGGREGATIONS:
            raise InvalidValueError("SgmCfg.aggregation", self.aggregation,
                                    "the path costs are summed by Warp kernels or torch ops",
                                    "pass 'auto', 'torch' or 'warp'")
        super().__post_init__()


def grey_levels(image: torch.Tensor) -> torch.Tensor:
    """(H, W) float32 integer grey levels 0 .. 255000 of (H, W, 3) RGB or (H, W) grey uint8.
    Integer weights (ITU-R 601 x 1000) keep the census comparisons identical on every device."""
    if image.ndim == 3:
        rgb = image.to(torch.int32)
        image = 299 * rgb[..., 0] + 587 * rgb[..., 1] + 114 * rgb[..., 2]
    else:
        image = image.to(torch.int32) * 1000
    return image.to(torch.float32)


def census(grey: torch.Tensor, rows: int, cols: int) -> torch.Tensor:
    """(H, W) int64 census signature: one bit per window pixel (centre excluded), set where the
    neighbour is darker than the centre. Borders repeat the edge pixels."""
    if rows * cols > 63 or rows % 2 == 0 or cols % 2 == 0:
        raise ValueError(f"the census window needs odd sides and at most 63 pixels, not {rows}x{cols}")
    h, w = grey.shape
    ry, rx = rows // 2, cols // 2
    padded = F.pad(grey[None, None], (rx, rx, ry, ry), mode="replicate")[0, 0]
    signature = torch.zeros((h, w), dtype=torch.int64, device=grey.device)
    offsets = [(dy, dx) for dy in range(rows) for dx in range(cols) if (dy, dx) != (ry, rx)]
    for bit, (dy, dx) in enumerate(offsets):
        signature |= (padded[dy:dy + h, dx:dx + w] < grey).to(torch.int64) << bit
    return signature


def popcount(x: torch.Tensor) -> torch.Tensor:
    """Set bits of each non-negative int64 (below 2^63), as int64 (torch has no popcount)."""
    x = x - ((x >> 1) & 0x5555555555555555)
    x = (x & 0x3333333333333333) + ((x >> 2) & 0x3333333333333333)
    x = (x + (x >> 4)) & 0x0F0F0F0F0F0F0F0F
    x = x + (x >> 8)
    x = x + (x >> 16)
    x = x + (x >> 32)
    return x & 0x7F


def _chunk_elements(device: torch.device) -> int:
    """Size of the int64 temporaries of the cost computation, which sets its disparity chunk: on
    the CPU one that stays in cache (8 MB; 32-128 MB ran 4-5x slower), on a GPU few launches
    (128 MB)."""
    return 1 << 20 if device.type == "cpu" else 1 << 24


def census_cost(left: torch.Tensor, right: torch.Tensor, num_disparities: int) -> torch.Tensor:
    """(D, H, W) float32 Hamming distance between the left census at x and the right one at x - d.
    Where x - d falls off the right image the cost is the largest possible (every bit differs)."""
    h, w = left.shape
    d_max = num_disparities - 1
    # shifted[y, j, x] = right[y, x - (d_max - j)]: disparity d sits at j = d_max - d
    shifted = F.pad(right, (d_max, 0)).unfold(1, w, 1)  # (H, D, W), a view
    cost = torch.empty((num_disparities, h, w), dtype=torch.float32, device=left.device)
    chunk = max(1, _chunk_elements(left.device) // (h * w))
    for d0 in range(0, num_disparities, chunk):
        d1 = min(d0 + chunk, num_disparities)
        right_d = shifted[:, d_max + 1 - d1:d_max + 1 - d0]  # disparities d1 - 1 .. d0
        cost[d0:d1] = popcount(left[:, None] ^ right_d).flip(1).permute(1, 0, 2)
    x = torch.arange(w, device=left.device)
    disparity = torch.arange(num_disparities, device=left.device)[:, None]
    return cost.masked_fill_((x < disparity)[:, None, :], 64.0)  # above any Hamming distance


def _scan(cost: torch.Tensor, p1: int, p2: int, shifts: tuple[int, ...]) -> torch.Tensor:
    """Sum over paths of Hirschmüller's path costs, every path scanning along dim 0.

    cost: (N, B, D, M) costs of B batched scans over N lines of M pixels each.
    shifts: one per path of a batch, P = len(shifts): the previous pixel along path k sits at
    m - shifts[k] on the previous line (0: straight, +-1: diagonal).
    Returns (N, B, D, M): the P path costs of every batch summed.

    L(p, d) = C(p, d) + min(L(q, d), L(q, d +- 1) + p1, min_k L(q, k) + p2) - min_k L(q, k) for q
    the previous pixel. Kept as N(q) = L(q) - min_k L(q, k) (>= 0) this is
    L(p, d) = C(p, d) + min(N(q, d), N(q, d +- 1) + p1, p2), and N = 0 before the image starts a
    path with L = C.
    """
    n, b, d, m = cost.shape
    total = torch.empty_like(cost)
    # N of the previous line with a zero column either side, so that a diagonal path's previous
    # pixel is a shifted view, and outside the image it starts the path
    prev = cost.new_zeros((b, len(shifts), d, m + 2))
    prev_inner = prev[..., 1:m + 1]
    prev_shifted = [prev[:, k, :, 1 - s:1 - s + m] for k, s in enumerate(shifts)]
    straight = shifts == (0,)
    # Buffers and their views made once: a step is then 8 or 9 kernels and no Python-side tensors,
    # which matters on a GPU, where launching costs more than computing at this size.
    before = prev_inner if straight else torch.empty_like(prev_inner)
    path, step = torch.empty_like(before), torch.empty_like(before)
    low = before.new_empty((b, len(shifts), 1, m))
    lower, upper = path[:, :, 1:], path[:, :, :-1]
    from_below, from_above = step[:, :, :-1], step[:, :, 1:]
    for cost_i, total_i in zip(cost.unsqueeze(2).unbind(0), total.unbind(0)):
        if not straight:
            torch.stack(prev_shifted, 1, out=before)
        torch.add(before, p1, out=step)
        torch.clamp_max(before, p2, out=path)
        torch.minimum(lower, from_below, out=lower)
        torch.minimum(upper, from_above, out=upper)
        path += cost_i
        torch.sum(path, 1, out=total_i)
        torch.amin(path, 2, keepdim=True, out=low)
        torch.sub(path, low, out=prev_inner)
    return total


def _scan_both_ways(cost: torch.Tensor, p1: int, p2: int, shifts: tuple[int, ...]) -> torch.Tensor:
    """(N, D, M) sum of the path costs of ``_scan`` over dim 0 forwards and backwards, batched."""
    both = _scan(torch.stack([cost, cost.flip(0)], 1), p1, p2, shifts)
    return both[:, 0] + both[:, 1].flip(0)


def aggregate(cost: torch.Tensor, cfg: SgmCfg) -> torch.Tensor:
    """(D, H, W) float32 sum of the semi-global path costs over ``cfg.paths`` directions.
    Peak memory: about six (D, H, W) float32 volumes."""
    if cfg.paths not in (4, 8):
        raise ValueError(f"paths must be 4 or 8, not {cfg.paths}")
    # left to right and back: scan over x, the lines are image columns
    total = _scan_both_ways(cost.permute(2, 0, 1), cfg.p1, cfg.p2, (0,)).permute(1, 2, 0)
    # top to bottom and back, with the four diagonals when 8 paths: scan over y
    shifts = (1, 0, -1) if cfg.paths == 8 else (0,)
    total += _scan_both_ways(cost.permute(1, 0, 2), cfg.p1, cfg.p2, shifts).permute(1, 0, 2)
    return total


def resolve_aggregation(aggregation: str, device: torch.device) -> str:
    """"torch" or "warp": who aggregates for ``SgmCfg.aggregation`` on ``device``. Imports Warp
    (through ``stereo.kernels``) only when asked about it, so the torch path needs no Warp."""
    if aggregation == "torch":
        return "torch"
    from . import kernels  # Warp is optional and slow to import

    if aggregation == "warp":
        if not kernels.available():
            raise ImportError("SgmCfg.aggregation='warp' needs warp-lang: pip install 'ambulo[perception]', "
                              "or pass aggregation='torch'")
        return "warp"
    return "warp" if kernels.available() and torch.device(device).type in ("cpu", "cuda") else "torch"


def aggregate_with(cost: torch.Tensor, cfg: SgmCfg) -> torch.Tensor:
    """``aggregate(cost, cfg)`` by whoever ``cfg.aggregation`` picks on the cost's device."""
    if resolve_aggregation(cfg.aggregation, cost.device) == "warp":
        from .kernels import aggregate_warp

        return aggregate_warp(cost, cfg)
    return aggregate(cost, cfg)


def _right_disparity(volume: torch.Tensor) -> torch.Tensor:
    """(H, W) int64 winner of the right image from the left-image volume: right pixel x matches
    left pixel x + d, so its cost at d is volume[d, :, x + d]."""
    d, h, w = volume.shape
    x = torch.arange(w, device=volume.device)
    disparity = torch.arange(d, device=volume.device)[:, None]
    src = x + disparity  # (D, W)
    shifted = volume.gather(2, src.clamp(max=w - 1)[:, None, :].expand(d, h, w))
    shifted.masked_fill_((src >= w)[:, None, :], float("inf"))
    return shifted.argmin(0)


def _median(disparity: torch.Tensor, size: int) -> torch.Tensor:
    """Median of the finite values in each size x size window (nan where there are none)."""
    r = size // 2
    padded = F.pad(disparity[None, None], (r, r, r, r), mode="replicate")
    windows = F.unfold(padded, size)[0]  # (size^2, H * W)
    return windows.nanmedian(0).values.view_as(disparity)


def select_disparity(volume: torch.Tensor, cfg: SgmCfg) -> torch.Tensor:
    """(H, W) float32 disparity, px, from the aggregated (D, H, W) volume; nan where rejected."""
    d, h, w = volume.shape
    best_cost, best = volume.min(0)
    levels = torch.arange(d, device=volume.device)[:, None, None]
    near = (levels - best).abs() <= 1
    runner_up = volume.masked_fill(near, float("inf")).amin(0)
    unique = runner_up >= best_cost * (1.0 + cfg.uniqueness_ratio)
    # Sub-pixel: a V of equal slopes through the costs at best - 1, best, best + 1 (Shimizu and
    # Okutomi 2005). Census costs grow about linearly off the match, so this is less biased towards
    # integers than a parabola: median error on Motorcycle 0.139 px (parabola 0.153 px).
    below = volume.gather(0, (best - 1).clamp(min=0)[None])[0]
    above = volume.gather(0, (best + 1).clamp(max=d - 1)[None])[0]
    slope = torch.maximum(below, above) - best_cost
    inner = (best > 0) & (best < d - 1) & (slope > 0)
    offset = torch.where(inner, (below - above) / (2 * slope.clamp(min=1.0)), 0.0)  # integer costs
    disparity = best.to(torch.float32) + offset
    # left-right check at the integer winner; disparity 0 (infinitely far) is no match, as in SGBM
    right = _right_disparity(volume)
    x = torch.arange(w, device=volume.device)
    partner = (x - best).clamp(min=0)
    consistent = ((right.gather(1, partner) - best).abs() <= cfg.max_lr_diff_px) & (x >= best)
    disparity = torch.where(unique & consistent & (best > 0), disparity, float("nan"))
    if cfg.median_size > 1:
        disparity = torch.where(disparity.isnan(), disparity, _median(disparity, cfg.median_size))
    return disparity


def sgm_disparity(left: torch.Tensor, right: torch.Tensor, cfg: SgmCfg | None = None) -> torch.Tensor:
    """(H, W) float32 disparity of the left image, px, on the images' device; nan where no match
    passed the checks. ``left`` / ``right``: rectified (H, W, 3) RGB or (H, W) grey, uint8, on one
    device. Memory: a few (D, H, W) float32 volumes (about 100 MB each at 500x741, D = 64)."""
    if left.shape != right.shape or left.dtype != torch.uint8 or right.dtype != torch.uint8:
        raise ValueError(f"need two uint8 images of one shape, not {left.dtype} {tuple(left.shape)} and "
                         f"{right.dtype} {tuple(right.shape)}")
    cfg = cfg or SgmCfg()
    signatures = [census(grey_levels(img), cfg.census_rows, cfg.census_cols) for img in (left, right)]
    volume = aggregate_with(census_cost(*signatures, cfg.num_disparities), cfg)
    return select_disparity(volume, cfg)


class CudaGraphSgm:
    """``sgm_disparity`` recorded once as a CUDA graph for one image shape and replayed per pair.

    Eager torch launches each of its kernels from Python (~12 000 torch ops at 500x741 with the torch
    aggregation, mostly the 2 x (H + W) path-scan steps; ~900 with Warp's, mostly the census); a
    replay launches them all at once. The images are copied into the graph's own input buffers, and
    the returned disparity is a fresh tensor.

    With the Warp aggregation (``cfg.aggregation`` "auto" or "warp", ``self.aggregation``) the Warp
    kernel is captured into the same torch graph: ``aggregate_warp`` launches it on torch's current
    stream, which during the capture is the capture stream, and the capture is registered with Warp
    as an external one (``wp.capture_begin(external=True)``, as Warp's own torch-interop tests do)
    so that Warp keeps the kernel's module loaded for the graph's lifetime. The warm-up before the
    capture loads (compiles) the module and wraps the capture stream for Warp, neither of which may
    happen inside a capture on older drivers. Not yet run on a GPU when written: if the capture
    fails, pass ``SgmCfg(aggregation="torch")``.
    """

    def __init__(self, shape: tuple[int, ...], cfg: SgmCfg | None = None, device: str | torch.device = "cuda"):
        cfg = cfg or SgmCfg()
        self.left = torch.zeros(shape, dtype=torch.uint8, device=device)
        self.right = torch.zeros_like(self.left)
        device = self.left.device
        self.aggregation = resolve_aggregation(cfg.aggregation, device)
        """"warp" or "torch": who aggregates in the graph."""
        # Warm up on the capture stream (a side stream, as torch.cuda.graph requires): the first
        # calls allocate, pick kernels and load Warp's module, which must not happen during capture.
        stream = torch.cuda.Stream(device=device)
        stream.wait_stream(torch.cuda.current_stream(device))
        with torch.cuda.stream(stream):
            sgm_disparity(self.left, self.right, cfg)
        torch.cuda.current_stream(device).wait_stream(stream)
        self.graph = torch.cuda.CUDAGraph()
        with torch.cuda.graph(self.graph, stream=stream):
            with self._warp_capture(device):
                self.disparity = sgm_disparity(self.left, self.right, cfg)

    @contextmanager
    def _warp_capture(self, device: torch.device):
        """Register torch's ongoing capture on the current stream with Warp (Warp aggregation only)."""
        if self.aggregation != "warp":
            yield
            return
        from .kernels import warp_stream, wp

        stream = warp_stream(device)
        # GLOBAL: the mode torch.cuda.graph opened the capture with (Warp uses it only to resume one)
        wp.capture_begin(stream=stream, external=True, force_module_load=False, capture_mode=wp.CaptureMode.GLOBAL)
        try:
            yield
        finally:
            self._warp_graph = wp.capture_end(stream=stream)  # holds the modules the graph uses

    def __call__(self, left: torch.Tensor, right: torch.Tensor) -> torch.Tensor:
        self.left.copy_(left)
        self.right.copy_(right)
        self.graph.replay()
        return self.disparity.clone()


def disparity_to_depth(disparity: torch.Tensor, focal_px: float, baseline_m: float) -> torch.Tensor:
    """(H, W) float32 depth, m, 0 where the disparity is missing: z = f b / d (as
    ``stereo.sgbm_opencv.disparity_to_depth``, for tensors)."""
    depth = focal_px * baseline_m / disparity
    return torch.where(torch.isfinite(depth) & (depth > 0), depth, 0.0).to(torch.float32)


def stereo_frame(left: torch.Tensor, right: torch.Tensor, intrinsics: torch.Tensor, baseline_m: float,
                 cfg: SgmCfg | None = None, time_s: float = 0.0) -> RgbdFrame:
    """An ``RgbdFrame`` of the left camera from a rectified pair, for the mapper.
    intrinsics: (3, 3) K of the left camera; baseline_m: distance between the optical centres, m."""
    k = torch.as_tensor(intrinsics, dtype=torch.float64)
    depth = disparity_to_depth(sgm_disparity(left, right, cfg), float(k[0, 0]), baseline_m)
    return RgbdFrame(depth_m=depth, rgb=left if left.ndim == 3 else None, intrinsics=k, time_s=time_s)


__all__ = ["AGGREGATIONS", "CudaGraphSgm", "SgmCfg", "aggregate", "aggregate_with", "census", "census_cost",
           "disparity_to_depth", "grey_levels", "popcount", "resolve_aggregation", "select_disparity", "sgm_disparity",
           "stereo_frame"]
