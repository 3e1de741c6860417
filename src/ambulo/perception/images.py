"""PNG pictures of 2-D maps for people to look at: occupancy, costmap (with the path walked) and
steppability, drawn with y up (row 0 of the array is the bottom of the picture)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from .costmap import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION, Costmap
from .slices import OCCUPIED, UNKNOWN, Slice2D


def _to_numpy(t) -> np.ndarray:
    return t.detach().cpu().numpy() if isinstance(t, torch.Tensor) else np.asarray(t)


def occupancy_rgb(occupancy: Slice2D) -> np.ndarray:
    """(H, W, 3) uint8: unknown grey, free white, occupied black."""
    data = _to_numpy(occupancy.data)
    rgb = np.full((*data.shape, 3), 255, np.uint8)
    rgb[data == UNKNOWN] = (150, 150, 160)
    rgb[data == OCCUPIED] = (0, 0, 0)
    return rgb


def costmap_rgb(costmap: Costmap) -> np.ndarray:
    """(H, W, 3) uint8: free white, decaying cost yellow to red, inscribed purple, lethal black,
    unknown grey (the colours RViz's "costmap" scheme uses)."""
    c = _to_numpy(costmap.cost).astype(np.int64)
    t = np.clip(c / 252.0, 0, 1)[..., None]
    rgb = ((1 - t) * np.array([255, 255, 255]) + t * np.array([220, 30, 30])).astype(np.uint8)
    rgb[(c > 0) & (c < INSCRIBED_INFLATED_OBSTACLE)] = (
        (1 - t[(c > 0) & (c < INSCRIBED_INFLATED_OBSTACLE)]) * np.array([255, 230, 60])
        + t[(c > 0) & (c < INSCRIBED_INFLATED_OBSTACLE)] * np.array([220, 30, 30])).astype(np.uint8)
    rgb[c == INSCRIBED_INFLATED_OBSTACLE] = (120, 40, 160)
    rgb[c == LETHAL_OBSTACLE] = (0, 0, 0)
    rgb[c == NO_INFORMATION] = (150, 150, 160)
    return rgb


def draw_path(rgb: np.ndarray, grid: Slice2D, xy_m: np.ndarray, color=(30, 90, 230)) -> np.ndarray:
    """``rgb`` with world points (N, 2) drawn as 2x2-pixel dots."""
    out = rgb.copy()
    iy, ix = grid.cells_of(xy_m)
    for dy in (0, 1):
        for dx in (0, 1):
            ok = (iy + dy >= 0) & (iy + dy < out.shape[0]) & (ix + dx >= 0) & (ix + dx < out.shape[1])
            out[iy[ok] + dy, ix[ok] + dx] = color
    return out


def write_png(path: str | Path, rgb: np.ndarray, scale: int = 4) -> Path:
    """Write a map picture, y up, each cell ``scale`` x ``scale`` pixels."""
    import imageio.v3 as iio

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    big = np.repeat(np.repeat(rgb[::-1], scale, axis=0), scale, axis=1)
    iio.imwrite(path, big)
    return path


__all__ = ["costmap_rgb", "draw_path", "occupancy_rgb", "write_png"]
