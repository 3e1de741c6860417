"""Stereo depth on the CPU: OpenCV's semi-global block matching (Hirschmüller 2008, ``StereoSGBM``)
on a rectified pair, and disparity -> metric depth for the mapper (z = f * baseline / disparity)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...utils.validate import Checked


@dataclass(kw_only=True)
class SgbmCfg(Checked):
    """SGBM settings; the smoothness penalties follow OpenCV's documented choice
    P1 = 8 * channels * block^2, P2 = 32 * channels * block^2."""

    num_disparities: int = 64
    """Search range, px (a multiple of 16; the Middlebury Motorcycle pair skimage ships goes to 60)."""
    block_size: int = 5
    uniqueness_ratio: int = 10
    speckle_window: int = 100
    speckle_range: int = 2


def sgbm_disparity(left: np.ndarray, right: np.ndarray, cfg: SgbmCfg | None = None) -> np.ndarray:
    """(H, W) float32 disparity of the left image, px; ``nan`` where SGBM found no match.
    ``left`` / ``right``: rectified (H, W, 3) uint8 RGB or (H, W) grey."""
    import cv2  # perception extra

    cfg = cfg or SgbmCfg()
    grey = [cv2.cvtColor(img, cv2.COLOR_RGB2GRAY) if img.ndim == 3 else img for img in (left, right)]
    b = cfg.block_size
    matcher = cv2.StereoSGBM_create(minDisparity=0, numDisparities=cfg.num_disparities, blockSize=b,
                                    P1=8 * b * b, P2=32 * b * b, uniquenessRatio=cfg.uniqueness_ratio,
                                    speckleWindowSize=cfg.speckle_window, speckleRange=cfg.speckle_range,
                                    mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
    disparity = matcher.compute(grey[0], grey[1]).astype(np.float32) / 16.0  # fixed point, 4 fractional bits
    disparity[disparity <= 0] = np.nan
    return disparity


def disparity_to_depth(disparity: np.ndarray, focal_px: float, baseline_m: float) -> np.ndarray:
    """(H, W) float32 depth, m (0 where the disparity is missing): z = f b / d."""
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = focal_px * baseline_m / disparity
    return np.where(np.isfinite(depth) & (depth > 0), depth, 0.0).astype(np.float32)


__all__ = ["SgbmCfg", "disparity_to_depth", "sgbm_disparity"]
