"""Feature front ends of ``RgbdOdometry``: keypoints, descriptors, their 3-D points from the depth
image, and descriptor matching. Both hand the tracker torch tensors on its device.

- ``OrbFeatures``: OpenCV's ORB (Rublee et al. 2011) and a brute-force Hamming matcher, on the host.
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
from typing import TYPE_CHECKING, Literal

import numpy as np
import torch

if TYPE_CHECKING:
    from .vo import VoCfg


@dataclass(kw_only=True)
class KorniaFeaturesCfg:
    """The kornia front end. The defaults were chosen on the seeded head-camera walk (300 frames,
    640x480, CPU; benchmarks/results/cpu-2026-11-24-vo.md): every Shi-Tomasi variant tried (NMS
    window, quality, corner count, ratio, oriented or 32 px patches) tracked within 0.11-0.20 cm
    ATE, so the cheapest won: upright 16 px patches take half the time of oriented or 32 px ones."""

    response: Literal["gftt", "harris"] = "gftt"
    """Corner response: Shi-Tomasi's min eigenvalue (``gftt_response``) or Harris. Harris measured
    worse (0.31 cm ATE against 0.13, with ``min_response`` lowered to 1e-8 for its ~80x smaller
    response; at 1e-6 it keeps ~140 corners and loses track)."""
    nms_window_px: int = 3
    """Non-maximum suppression window (odd), px."""
    quality: float = 0.001
    """Corners weaker than this fraction of the frame's strongest are dropped (OpenCV's
    ``goodFeaturesToTrack`` calls it ``qualityLevel``)."""
    min_response: float = 1e-6
    """Absolute floor of the response (image in [0, 1], kornia's normalised Sobel): keeps a black or
    uniform frame, whose strongest response is round-off, from yielding corners."""
    border_px: int = 16
    """Corners this close to the image border are dropped (their patch would leave the image)."""
    patch_radius_px: float = 16.0
    """Half the side of the square image region a descriptor describes, px (ORB's patch is 31 px)."""
    descriptor_patch_px: int = 16
    """SIFT patch side, px. The region (2 x ``patch_radius_px``) is sampled from the pyramid level
    that gives it this many pixels: 16 of a 32 px region reads the half-resolution level, smoothed
    by ``pyrdown`` rather than aliased."""
    orient: bool = False
    """Rotate each patch to its dominant gradient (``LAFOrienter``) for roll invariance. A walking
    head camera barely rolls: upright descriptors match better and cost less."""


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
                   depth_range_m: tuple[float, float]) -> tuple[torch.Tensor, torch.Tensor]:
    """Camera-frame 3-D points (N, 3) float64, m, at ``pixels`` (N, 2) and their validity (N,) bool:
    depth at the nearest pixel of ``depth_m`` (H, W) float32, rejected across depth edges (the 3x3
    neighbourhood must agree within 2 %) and outside ``depth_range_m``."""
    h, w = depth_m.shape
    u = pixels[:, 0].round().long().clamp(1, w - 2)
    v = pixels[:, 1].round().long().clamp(1, h - 2)
    step = torch.tensor([-1, 0, 1], device=depth_m.device)
    patch = depth_m[(v[:, None, None] + step[None, :, None]), (u[:, None, None] + step[None, None, :])].flatten(1)
    z = depth_m[v, u]
    lo, hi = depth_range_m
    low, high = patch.amin(-1), patch.amax(-1)
    valid = (low > 0) & (high - low < 0.02 * z) & (z > lo) & (z < hi)
    z64 = z.double()
    x = (pixels[:, 0] - k[0, 2]) / k[0, 0] * z64
    y = (pixels[:, 1] - k[1, 2]) / k[1, 1] * z64
    return torch.stack([x, y, z64], -1), valid


class OrbFeatures:
    """OpenCV ORB keypoints and a Hamming matcher with Lowe's ratio test; host (CPU) tensors."""

    def __init__(self, cfg: VoCfg, k: torch.Tensor):
        import cv2  # noqa: PLC0415 - perception extra

        self.cv2, self.cfg, self.k = cv2, cfg, k
        self.orb = cv2.ORB_create(nfeatures=cfg.num_features, fastThreshold=cfg.fast_threshold)
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
        points_c, valid = lift_keypoints(pixels, depth, self.k, self.cfg.depth_range_m)
        return FrameFeatures(pixels=pixels, descriptors=torch.from_numpy(des), points_c=points_c, valid=valid)

    def match(self, descriptors: torch.Tensor, map_descriptors: torch.Tensor) -> torch.Tensor:
        """(M, 2) int64 index pairs (query, map) passing the ratio test and ``max_hamming``."""
        if len(descriptors) < 2 or len(map_descriptors) < 2:
            return torch.zeros((0, 2), dtype=torch.long)
        pairs = [(m[0].queryIdx, m[0].trainIdx)
                 for m in self.matcher.knnMatch(descriptors.numpy(), map_descriptors.numpy(), k=2)
                 if len(m) == 2 and m[0].distance < self.cfg.ratio_test * m[1].distance
                 and m[0].distance <= self.cfg.max_hamming]
        return torch.tensor(pairs, dtype=torch.long).reshape(-1, 2)


class KorniaFeatures:
    """Shi-Tomasi (or Harris) corners with upright RootSIFT descriptors, all in torch on ``device``.

    Per frame the only host read is the number of corners found (to size the keypoint tensors).
    On CUDA, cuDNN's TF32 convolutions are switched off inside ``detect`` so that CPU and CUDA find
    the same corners (TF32 rounds the response to 10 mantissa bits, which reorders near-equal peaks).
    """

    def __init__(self, cfg: VoCfg, k: torch.Tensor, device: torch.device):
        import kornia.feature as kf  # noqa: PLC0415 - perception extra

        self.kf, self.cfg, self.kcfg, self.k, self.device = kf, cfg, cfg.kornia, k, device
        self.response = kf.gftt_response if self.kcfg.response == "gftt" else kf.harris_response
        self.sift = kf.SIFTDescriptor(self.kcfg.descriptor_patch_px, 8, 4, rootsift=True).to(device)
        self.orienter = kf.LAFOrienter(32).to(device) if self.kcfg.orient else None

    def detect(self, rgb, depth_m) -> FrameFeatures:
        """``rgb`` (H, W, 3) uint8 and ``depth_m`` (H, W) metres, numpy or torch (any device)."""
        from kornia.color import rgb_to_grayscale  # noqa: PLC0415
        from kornia.geometry.subpix import nms2d  # noqa: PLC0415

        c = self.kcfg
        rgb = torch.as_tensor(rgb).to(self.device)
        depth = torch.as_tensor(depth_m).to(self.device, torch.float32)
        with torch.no_grad(), _exact_fp32_convolutions(self.device):
            gray = rgb_to_grayscale(rgb.permute(2, 0, 1)[None].float() / 255.0)  # (1, 1, H, W) in [0, 1]
            h, w = gray.shape[-2:]
            response = torch.zeros_like(gray)
            b = c.border_px
            response[..., b:h - b, b:w - b] = self.response(gray)[..., b:h - b, b:w - b]
            peak = (nms2d(response, (c.nms_window_px, c.nms_window_px), mask_only=True)
                    & (response > c.quality * response.amax()) & (response > c.min_response))
            score, index = torch.where(peak, response, 0.0).flatten().topk(min(self.cfg.num_features, h * w))
            index = index[: int((score > 0).sum())]  # the one host read
            xy = torch.stack([index % w, index // w], -1).float()  # (N, 2), px
            n = len(xy)
            laf = self.kf.laf_from_center_scale_ori(xy[None], torch.full((1, n, 1, 1), c.patch_radius_px, device=self.device),
                                                    torch.zeros((1, n, 1), device=self.device))
            if self.orienter is not None and n:
                laf = self.orienter(laf, gray)
            patches = self.kf.extract_patches_from_pyramid(gray, laf, c.descriptor_patch_px)[0]  # (N, 1, P, P)
            descriptors = self.sift(patches) if n else torch.zeros((0, 128), device=self.device)
        pixels = xy.double()
        points_c, valid = lift_keypoints(pixels, depth, self.k, self.cfg.depth_range_m)
        return FrameFeatures(pixels=pixels, descriptors=descriptors, points_c=points_c, valid=valid)

    def match(self, descriptors: torch.Tensor, map_descriptors: torch.Tensor) -> torch.Tensor:
        """(M, 2) int64 index pairs (query, map): nearest neighbour in L2 with Lowe's ratio test."""
        if len(descriptors) < 2 or len(map_descriptors) < 2:
            return torch.zeros((0, 2), dtype=torch.long, device=self.device)
        with torch.no_grad():
            _, pairs = self.kf.match_snn(descriptors, map_descriptors, self.cfg.ratio_test)
        return pairs


def _exact_fp32_convolutions(device: torch.device):
    """A context with cuDNN's TF32 off (the caller's settings return after); nothing on the CPU."""
    if device.type != "cuda":
        return contextlib.nullcontext()
    cudnn = torch.backends.cudnn
    return cudnn.flags(enabled=cudnn.enabled, benchmark=cudnn.benchmark, deterministic=cudnn.deterministic,
                       allow_tf32=False)


def make_features(cfg: VoCfg, k: torch.Tensor, device: torch.device) -> OrbFeatures | KorniaFeatures:
    return OrbFeatures(cfg, k) if cfg.features == "orb" else KorniaFeatures(cfg, k, device)


__all__ = ["FrameFeatures", "KorniaFeatures", "KorniaFeaturesCfg", "OrbFeatures", "lift_keypoints", "make_features"]
