"""Feature front ends of ``RgbdOdometry``: keypoints, descriptors, their 3-D points from the depth
image, and descriptor matching. Both hand the tracker torch tensors on its device.

- ``OrbFeatures``: OpenCV's ORB (Rublee et al. 2011) and a brute-force Hamming matcher (or the
  guided one, ``vo.guided``), on the host; the tensors it hands over live on the tracker's device.
- ``KorniaFeatures``: weight-free kornia parts on any torch device (CPU or CUDA, the same code):
  Shi-Tomasi corners (``gftt_response``, kornia's ``nms2d``, top-k), SIFT descriptors of upright
  patches (``laf_from_center_scale_ori``, ``extract_patches_from_pyramid``, ``SIFTDescriptor`` with
  RootSIFT; optional ``LAFOrienter``, the dominant gradient), and Lowe's ratio test on descriptor
  distances (``match_snn``). None of these loads weights (kornia's learned detectors and
  descriptors would download them, which is not allowed here).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass

import numpy as np
import torch

from .config import VoCfg
from .guided import best_two, hamming, window_pairs


@dataclass
class FrameFeatures:
    """Keypoints of one frame, on the tracker's device."""

    pixels: torch.Tensor
    """(N, 2) float64 keypoint positions (u, v), px, pixel centres at integers."""
    descriptors: torch.Tensor
    """(N, D) descriptors: uint8 (ORB, D = 32 bytes) or float32 (RootSIFT, D = 128)."""
    points_c: torch.Tensor
    """(N, 3) float64 keypoints back-projected with the depth image (camera frame, OpenCV axes), m."""
    valid: torch.Tensor
    """(N,) bool: the keypoint's depth is usable (in range, not across a depth edge)."""


def lift_keypoints(pixels: torch.Tensor, depth_m: torch.Tensor, k: torch.Tensor,
                   depth_range_m: tuple[float, float],
                   edge_fraction: float = 0.02) -> tuple[torch.Tensor, torch.Tensor]:
    """Camera-frame 3-D points (N, 3) float64, m, at ``pixels`` (N, 2) and their validity (N,) bool:
    depth is the median of the 3x3 neighbourhood of the nearest pixel of ``depth_m`` (H, W) float32
    (the centre on a noise-free plane; under per-pixel depth noise the median is ~2x steadier than
    one pixel), rejected next to a hole (0 = no depth, e.g. sensor dropout), across depth edges (the
    neighbourhood must agree within ``edge_fraction`` of the depth) and outside ``depth_range_m``."""
    h, w = depth_m.shape
    uv = pixels.round().long()
    flat = uv[:, 1].clamp(1, h - 2) * w + uv[:, 0].clamp(1, w - 2)  # (N,) nearest pixel, row-major
    # the 3x3 neighbourhood as one gather at flat offsets (centre at 4)
    step = torch.tensor([-w - 1, -w, -w + 1, -1, 0, 1, w - 1, w, w + 1], device=depth_m.device)
    patch = depth_m.flatten()[flat[:, None] + step]  # (N, 9)
    z = patch.median(-1).values
    lo, hi = depth_range_m
    low, high = patch.amin(-1), patch.amax(-1)
    valid = (low > 0) & (high - low < edge_fraction * z) & (z > lo) & (z < hi)
    z64 = z.double()[:, None]
    return torch.cat([(pixels - k[:2, 2]) / k.diagonal()[:2] * z64, z64], -1), valid


class OrbFeatures:
    """OpenCV ORB keypoints and a Hamming matcher with Lowe's ratio test. Detection and matching run
    on the host; the frame's tensors and the matches are handed over on ``device`` (where the
    tracker keeps its map, refines and checks rigidity)."""

    def __init__(self, cfg: VoCfg, k: torch.Tensor, device: torch.device | str = "cpu"):
        import cv2  # perception extra

        self.cv2, self.cfg, self.k, self.device = cv2, cfg, k.cpu(), torch.device(device)
        self.orb = cv2.ORB_create(nfeatures=cfg.num_features, fastThreshold=cfg.fast_threshold,
                                  patchSize=cfg.orb_patch_px, edgeThreshold=cfg.orb_edge_px)
        self.matcher = cv2.BFMatcher(cv2.NORM_HAMMING)

    def detect(self, rgb, depth_m) -> FrameFeatures:
        """``rgb`` (H, W, 3) uint8 and ``depth_m`` (H, W) metres, numpy or torch."""
        rgb = np.asarray(rgb.cpu() if hasattr(rgb, "cpu") else rgb)
        depth = torch.as_tensor(np.asarray(depth_m.cpu() if hasattr(depth_m, "cpu") else depth_m, np.float32))
        gray = self.cv2.cvtColor(np.ascontiguousarray(rgb), self.cv2.COLOR_RGB2GRAY)
        kps, des = self.orb.detectAndCompute(gray, None)
        if des is None or len(kps) == 0:
            des, kps = np.zeros((0, 32), np.uint8), []
        pixels = torch.tensor([kp.pt for kp in kps], dtype=torch.float64).reshape(-1, 2)
        points_c, valid = lift_keypoints(pixels, depth, self.k, self.cfg.depth_range_m, self.cfg.depth_edge_fraction)
        d = self.device
        return FrameFeatures(pixels=pixels.to(d), descriptors=torch.from_numpy(des).to(d), points_c=points_c.to(d),
                             valid=valid.to(d))

    def match(self, descriptors: torch.Tensor, map_descriptors: torch.Tensor) -> torch.Tensor:
        """(M, 2) int64 index pairs (query, map) passing the ratio test and ``max_hamming``."""
        if len(descriptors) < 2 or len(map_descriptors) < 2:
            return torch.zeros((0, 2), dtype=torch.long, device=self.device)
        pairs = [(m[0].queryIdx, m[0].trainIdx)
                 for m in self.matcher.knnMatch(descriptors.cpu().numpy(), map_descriptors.cpu().numpy(), k=2)
                 if len(m) == 2 and m[0].distance < self.cfg.ratio_test * m[1].distance
                 and m[0].distance <= self.cfg.max_hamming]
        return torch.tensor(pairs, dtype=torch.long).reshape(-1, 2).to(self.device)

    def match_window(self, descriptors: torch.Tensor, pixels: torch.Tensor, map_descriptors: torch.Tensor,
                     map_pixels: torch.Tensor, window_px: float) -> torch.Tensor:
        """``match`` among the map points whose predicted pixels ``map_pixels`` (M, 2) (non-finite:
        not in view) lie within ``window_px`` of the keypoint's ``pixels`` (N, 2) (``vo.guided``)."""
        q, m = window_pairs(pixels.cpu().numpy(), map_pixels.cpu().numpy(), window_px)
        dist = hamming(descriptors.cpu().numpy()[q], map_descriptors.cpu().numpy()[m])
        queries, best, second = best_two(q, dist)
        d = dist[best]
        keep = (d < self.cfg.ratio_test * second) & (d <= self.cfg.max_hamming)
        return torch.from_numpy(np.stack([queries[keep], m[best[keep]]], 1)).reshape(-1, 2).to(self.device)


class KorniaFeatures:
    """Shi-Tomasi (or Harris) corners with upright RootSIFT descriptors, all in torch on ``device``.

    Per frame the only host read is the number of corners found (to size the keypoint tensors).
    On CUDA, cuDNN's TF32 convolutions are switched off inside ``detect`` so that CPU and CUDA find
    the same corners (TF32 rounds the response to 10 mantissa bits, which reorders near-equal peaks).
    """

    def __init__(self, cfg: VoCfg, k: torch.Tensor, device: torch.device):
        import kornia.feature as kf  # perception extra

        self.kf, self.cfg, self.kcfg, self.k, self.device = kf, cfg, cfg.kornia, k, device
        self.sift = kf.SIFTDescriptor(self.kcfg.descriptor_patch_px, 8, 4, rootsift=True).to(device)
        self.orienter = kf.LAFOrienter(32).to(device) if self.kcfg.orient else None
        self._grids: dict[tuple[int, int], dict | None] = {}
        self._sift_parts = _kornia_sift_parts()
        self._blur = _kornia_blur_parts(device)
        # the grouped convolution's weight (B, 1, k, k) and the bin indices, made once
        self._pk_weight = self.sift.pk.weight.detach().repeat(self.sift.num_ang_bins, 1, 1, 1)
        self._bins = torch.arange(self.sift.num_ang_bins, device=device, dtype=torch.float32).view(1, -1, 1, 1)

    def detect(self, rgb, depth_m) -> FrameFeatures:
        """``rgb`` (H, W, 3) uint8 and ``depth_m`` (H, W) metres, numpy or torch (any device)."""
        from kornia.color import rgb_to_grayscale
        from kornia.geometry.subpix import nms2d

        c = self.kcfg
        rgb = torch.as_tensor(rgb).to(self.device)
        depth = torch.as_tensor(depth_m).to(self.device, torch.float32)
        with torch.no_grad(), _exact_fp32_convolutions(self.device):
            gray = rgb_to_grayscale(rgb.permute(2, 0, 1)[None].float() / 255.0)  # (1, 1, H, W) in [0, 1]
            h, w = gray.shape[-2:]
            response = torch.zeros_like(gray)
            b = c.border_px
            response[..., b:h - b, b:w - b] = self._response(gray)[..., b:h - b, b:w - b]
            peak = (self._nms(response, nms2d)
                    & (response > c.quality * response.amax()) & (response > c.min_response))
            score, index = torch.where(peak, response, 0.0).flatten().topk(min(self.cfg.num_features, h * w))
            index = index[: int((score > 0).sum())]  # the one host read
            xy = torch.stack([index % w, index // w], -1).float()  # (N, 2), px
            n = len(xy)
            if not n:
                descriptors = torch.zeros((0, 128), device=self.device)
            elif self.orienter is not None or self._patch_grid(h, w) is None:
                laf = self.kf.laf_from_center_scale_ori(xy[None], torch.full((1, n, 1, 1), c.patch_radius_px,
                                                                             device=self.device),
                                                        torch.zeros((1, n, 1), device=self.device))
                if self.orienter is not None:
                    laf = self.orienter(laf, gray)
                descriptors = self._sift(self.kf.extract_patches_from_pyramid(gray, laf, c.descriptor_patch_px)[0])
            else:
                descriptors = self._sift(self._upright_patches(gray, xy))  # (N, 1, P, P) patches
        pixels = xy.double()
        points_c, valid = lift_keypoints(pixels, depth, self.k, self.cfg.depth_range_m, self.cfg.depth_edge_fraction)
        return FrameFeatures(pixels=pixels, descriptors=descriptors, points_c=points_c, valid=valid)

    def _nms(self, response: torch.Tensor, nms2d) -> torch.Tensor:
        """(1, 1, H, W) bool strict local maxima: kornia's ``nms2d(..., mask_only=True)``. For a 3x3
        window a pixel must exceed the maximum of its 8 neighbours: maxima of three along rows, then of
        the rows above and below and of the left and right pixel (the outer ring is never a maximum),
        in ~15 ops instead of ~40."""
        c = self.kcfg
        if c.nms_window_px != 3:
            return nms2d(response, (c.nms_window_px, c.nms_window_px), mask_only=True)
        x = response[0, 0]  # (H, W)
        h, w = x.shape
        row_max = torch.maximum(torch.maximum(x[:, :-2], x[:, 1:-1]), x[:, 2:])  # (H, W - 2): columns j-1..j+1
        # the 8 neighbours: the rows above and below (3 each), then left and right
        neighbours = torch.maximum(torch.maximum(row_max[:-2], row_max[2:]),
                                   torch.maximum(x[1:-1, :-2], x[1:-1, 2:]))  # (H - 2, W - 2)
        peak = torch.zeros(h, w, dtype=torch.bool, device=response.device)
        peak[1:-1, 1:-1] = x[1:-1, 1:-1] > neighbours
        return peak[None, None]

    def _response(self, gray: torch.Tensor) -> torch.Tensor:
        """(1, 1, H, W) corner response. Shi-Tomasi is kornia's ``gftt_response`` with the three
        structure-tensor products blurred in one ``gaussian_blur2d`` call (one kernel and one pass
        instead of three; per channel the same arithmetic, bit for bit); Harris is kornia's."""
        from kornia.filters import gaussian_blur2d, spatial_gradient

        if self.kcfg.response == "harris":
            return self.kf.harris_response(gray)
        grad = spatial_gradient(gray)[:, 0]  # (1, 2, H, W): dx, dy
        dx, dy = grad[:, :1], grad[:, 1:]
        products = torch.cat([dx**2, dy**2, dx * dy], 1)
        if self._blur is None:
            blurred = gaussian_blur2d(products, (7, 7), (1.0, 1.0))
        else:  # kornia's gaussian_blur2d with its kernels made once, not three times a frame
            cpu_eligible, separable, kernel, taps = self._blur
            blurred = (_blur_taps(products, taps) if cpu_eligible(products)
                       else separable(products, kernel, kernel, "reflect"))
        dx2, dy2, dxy = blurred.split(1, 1)
        trace_m = dx2 + dy2
        disc = (dx2 - dy2) ** 2 + 4.0 * dxy * dxy  # trace^2 - 4 det, never negative
        positive = disc > 0
        root = torch.where(positive, torch.where(positive, disc, torch.ones_like(disc)).sqrt(), 0.0)
        return 0.5 * (trace_m - root)  # the smaller eigenvalue

    def _upright_patches(self, gray: torch.Tensor, xy: torch.Tensor) -> torch.Tensor:
        """(N, 1, P, P) upright patches of side ``2 patch_radius_px`` around ``xy`` (N, 2) px, sampled
        with P pixels: kornia's ``extract_patches_from_pyramid`` for these LAFs, bit for bit, in
        ~20 ops instead of ~240. Every patch has the same scale, so all sample one pyramid level:
        only that level is built (kornia builds all of them), into an atlas of kornia's width so that
        the sampling coordinates round exactly as kornia's; the parts of the grid that do not depend
        on the keypoint are made once per image size (``_patch_grid``)."""
        from kornia.geometry.transform import pyrdown

        h, w = gray.shape[-2:]
        g = self._patch_grid(h, w)
        level_img = gray
        for _ in range(g["level"]):
            level_img = pyrdown(level_img)
        atlas = gray.new_zeros(1, 1, h + 2, g["atlas_w"])
        lh, lw = level_img.shape[-2:]
        atlas[:, :, : lh + 2, g["xoff"]: g["xoff"] + lw + 2] = torch.nn.functional.pad(level_img, (1, 1, 1, 1),
                                                                                         mode="replicate")
        # kornia's remap of the grid, op for op: the normalised LAF centre, then translation, clamp, level frame
        t = (2.0 * (xy * g["centre_coef"]) * g["size_m1"] + 1.0) / g["size"] - 1.0  # (N, 2)
        grid = (g["base"] + t[:, None, None]).maximum(g["lo"]).minimum(g["hi"]) * g["scale"] + g["offset"]
        p = self.kcfg.descriptor_patch_px
        out = torch.nn.functional.grid_sample(atlas, grid.view(1, len(xy) * p, p, 2), padding_mode="border",
                                              align_corners=False)
        return out.view(len(xy), 1, p, p)

    def _patch_grid(self, h: int, w: int) -> dict | None:
        """Per image size, made once: the pyramid level kornia picks, its atlas layout and the
        keypoint-independent grid ``base`` (P, P, 2) (``affine_grid`` of the normalised LAF times kornia's
        ``k``), computed with kornia's own functions on one LAF. None where kornia samples without an
        atlas (a one-level pyramid, or an atlas over its 128 MiB budget): ``detect`` then calls kornia."""
        if (h, w) in self._grids:
            return self._grids[(h, w)]
        import torch.nn.functional as F

        c, p, dev = self.kcfg, self.kcfg.descriptor_patch_px, self.device
        heights, widths = [h], [w]  # kornia's pyramid sizes (extract_patches_from_pyramid)
        for _ in range(1, max(1, min(h, w) // p)):
            if min(heights[-1], widths[-1]) <= 2 or min(heights[-1] // 2, widths[-1] // 2) < p:
                break
            heights.append(heights[-1] // 2)
            widths.append(widths[-1] // 2)
        if len(heights) == 1 or (h + 2) * sum(w_l + 2 for w_l in widths) * 4 > 128 * 1024 * 1024:
            self._grids[(h, w)] = None
            return None
        img = torch.zeros(1, 1, h, w, device=dev)
        laf = self.kf.laf_from_center_scale_ori(torch.zeros(1, 1, 2, device=dev),
                                                torch.full((1, 1, 1, 1), c.patch_radius_px, device=dev),
                                                torch.zeros((1, 1, 1), device=dev))
        nlaf = self.kf.normalize_laf(laf, img)
        scale = 2.0 * self.kf.get_laf_scale(self.kf.denormalize_laf(nlaf, img)) / float(p)
        level = int(scale.log2().clamp(min=0.0, max=float(len(heights) - 1)).long())
        wf, hf = float(max(w - 1, 1)), float(max(h - 1, 1))
        min_size = min(wf, hf)
        theta = torch.cat([nlaf[0, :, :, :2], torch.zeros(1, 2, 1, device=dev)], -1)
        base = F.affine_grid(theta, [1, 1, p, p], align_corners=False)[0] * torch.tensor(
            [2.0 * min_size / float(w), 2.0 * min_size / float(h)], device=dev)
        atlas_w, xoff = sum(w_l + 2 for w_l in widths), sum(w_l + 2 for w_l in widths[:level])
        h_l, w_l = heights[level], widths[level]
        coef = torch.ones(1, 1, 2, 3, device=dev) / min_size  # normalize_laf's, for the centre column
        coef[0, 0, 0, 2], coef[0, 0, 1, 2] = 1.0 / wf, 1.0 / hf

        def t32(*v):
            return torch.tensor(v, device=dev)

        self._grids[(h, w)] = {
            "level": level, "atlas_w": atlas_w, "xoff": xoff, "base": base, "centre_coef": coef[0, 0, :, 2],
            "size_m1": t32(wf, hf), "size": t32(float(w), float(h)),
            "lo": t32(-1.0 + 1.0 / float(w_l), -1.0 + 1.0 / float(h_l)),
            "hi": t32(1.0 - 1.0 / float(w_l), 1.0 - 1.0 / float(h_l)),
            "scale": t32(float(w_l) / float(atlas_w), float(h_l) / float(h + 2)),
            "offset": t32((float(w_l) + 2.0 * float(xoff + 1)) / float(atlas_w) - 1.0, (float(h_l) + 2.0) / float(h + 2) - 1.0),
        }
        return self._grids[(h, w)]

    def _sift(self, patches: torch.Tensor) -> torch.Tensor:
        """(N, 128) RootSIFT of (N, 1, P, P) patches: kornia's ``SIFTDescriptor.forward`` with its
        eight orientation bins pooled by one grouped convolution instead of eight convolutions
        (a Python loop of ~8 ops each)."""
        s = self.sift
        if self._sift_parts is None:
            return s(patches)
        magnitude_orientation, l2_normalize, rootsift = self._sift_parts
        from kornia.filters import spatial_gradient

        grads = spatial_gradient(patches, "diff")
        mag, ori = magnitude_orientation(grads[:, :, 0], grads[:, :, 1], s.eps)
        mag = mag * s.gk.expand_as(mag).type_as(mag)
        o_big = float(s.num_ang_bins) * ori / (2.0 * np.pi)
        bo0_big_ = torch.floor(o_big)
        wo1_big_ = o_big - bo0_big_
        bo0_big = bo0_big_ % s.num_ang_bins
        bo1_big = (bo0_big + 1) % s.num_ang_bins
        bins = self._bins  # (1, B, 1, 1)
        weighted = ((bo0_big == bins).to(patches.dtype) * ((1.0 - wo1_big_) * mag)
                    + (bo1_big == bins).to(patches.dtype) * (wo1_big_ * mag))  # (N, B, P, P)
        pk = s.pk
        ang_bins = torch.nn.functional.conv2d(weighted, self._pk_weight, None if pk.bias is None else
                                              pk.bias.repeat(s.num_ang_bins), pk.stride, pk.padding, pk.dilation,
                                              s.num_ang_bins).flatten(1)
        ang_bins = l2_normalize(ang_bins, dim=1)
        ang_bins = l2_normalize(torch.clamp(ang_bins, 0.0, float(s.clipval)), dim=1)
        return rootsift(ang_bins, s.eps) if s.rootsift else ang_bins

    def match(self, descriptors: torch.Tensor, map_descriptors: torch.Tensor) -> torch.Tensor:
        """(M, 2) int64 index pairs (query, map): nearest neighbour in L2 with Lowe's ratio test."""
        if len(descriptors) < 2 or len(map_descriptors) < 2:
            return torch.zeros((0, 2), dtype=torch.long, device=self.device)
        with torch.no_grad():
            _, pairs = self.kf.match_snn(descriptors, map_descriptors, self.cfg.ratio_test)
        return pairs

    def match_window(self, descriptors: torch.Tensor, pixels: torch.Tensor, map_descriptors: torch.Tensor,
                     map_pixels: torch.Tensor, window_px: float) -> torch.Tensor:
        """``match`` (Lowe's ratio as kornia's ``match_snn``: ``d1 <= ratio d2``) among the map points
        whose predicted pixels ``map_pixels`` (M, 2) (non-finite: not in view) lie within
        ``window_px`` of the keypoint's ``pixels`` (N, 2); a keypoint with one such point passes.
        The whole distance matrix, masked, on the device: no host read."""
        if not len(descriptors) or not len(map_descriptors):
            return torch.zeros((0, 2), dtype=torch.long, device=self.device)
        with torch.no_grad():
            dist = torch.cdist(descriptors, map_descriptors)
            far = torch.cdist(pixels.float(), map_pixels.float()) > window_px
            dist = dist.masked_fill(far | ~torch.isfinite(map_pixels).all(1), torch.inf)
            top, idx = dist.topk(min(2, dist.shape[1]), dim=1, largest=False)
            second = top[:, 1] if top.shape[1] > 1 else torch.full_like(top[:, 0], torch.inf)
            keep = torch.isfinite(top[:, 0]) & (top[:, 0] <= self.cfg.ratio_test * second)
            query = torch.arange(len(descriptors), device=self.device)
            return torch.stack([query[keep], idx[keep, 0]], 1)


def _kornia_sift_parts():
    """kornia's private SIFT steps ``(_gradient_magnitude_orientation, _l2_normalize, _rootsift)``,
    or None where this kornia lacks them (``KorniaFeatures._sift`` then calls the module)."""
    try:
        from kornia.feature.siftdesc import _gradient_magnitude_orientation, _l2_normalize, _rootsift
    except ImportError:
        return None
    return _gradient_magnitude_orientation, _l2_normalize, _rootsift


def _kornia_blur_parts(device: torch.device):
    """The steps of kornia's ``gaussian_blur2d(x, (7, 7), (1.0, 1.0))`` for float32 ``x``:
    ``(cpu_eligible, filter2d_separable, kernel (1, 7), taps)``: where kornia takes its CPU tap loop
    (``_blur_taps`` repeats it), else its separable convolution; the kernel made once by kornia's
    ``get_gaussian_kernel1d`` and ``taps`` its 7 weights as (1, 1, 1, 1) tensors. None where this
    kornia lacks the private CPU test."""
    try:
        from kornia.filters import filter2d_separable, get_gaussian_kernel1d
        from kornia.filters.gaussian import _gaussian_blur2d_cpu_eligible
    except ImportError:
        return None
    sigma = torch.tensor([[1.0, 1.0]], device=device)
    kernel = get_gaussian_kernel1d(7, sigma[:, 1].view(1, 1))
    taps = [kernel[:, tap, None, None, None] for tap in range(kernel.shape[-1])]
    return _gaussian_blur2d_cpu_eligible, filter2d_separable, kernel, taps


def _blur_taps(x: torch.Tensor, taps: list[torch.Tensor]) -> torch.Tensor:
    """kornia's ``_gaussian_blur2d_cpu`` (reflect border, the same kernel on both axes) op for op, so
    bit for bit, with the tap weights indexed once: ``x`` (B, C, H, W)."""
    radius = len(taps) // 2
    for axis in (-1, -2):
        size = x.shape[axis]
        padded = torch.nn.functional.pad(x, (radius, radius, 0, 0) if axis == -1 else (0, 0, radius, radius),
                                         mode="reflect")
        out = padded.narrow(axis, 0, size) * taps[0]
        for tap in range(1, len(taps)):
            out.addcmul_(padded.narrow(axis, tap, size), taps[tap])
        x = out
    return x


def _exact_fp32_convolutions(device: torch.device):
    """A context with cuDNN's TF32 off (the caller's settings return after); nothing on the CPU."""
    if device.type != "cuda":
        return contextlib.nullcontext()
    cudnn = torch.backends.cudnn
    return cudnn.flags(enabled=cudnn.enabled, benchmark=cudnn.benchmark, deterministic=cudnn.deterministic,
                       allow_tf32=False)


def make_features(cfg: VoCfg, k: torch.Tensor, device: torch.device) -> OrbFeatures | KorniaFeatures:
    return OrbFeatures(cfg, k, device) if cfg.features == "orb" else KorniaFeatures(cfg, k, device)


__all__ = ["FrameFeatures", "KorniaFeatures", "OrbFeatures", "lift_keypoints", "make_features"]
