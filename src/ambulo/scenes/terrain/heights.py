"""Terrain heights on the device: the generator's sample array, interpolated for any points.

Height scans, fall checks, spawning and the terrain curriculum ask "how high is the ground
here" for thousands of worlds every step. MuJoCo ray casts would answer too, but through the
collision pipeline and per ray; this is one gather and a bilinear blend over the same samples the
physics hfield is built from (``generator.add_terrain``), on the engine's device, with no host
sync. Points outside the grid read the nearest edge sample (the flat border).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch

from ...utils.validate import Checked, rule
from .generator import TerrainGrid


class TerrainHeights:
    """``height_at(xy)`` for (..., 2) world points, m, as float32 on ``device``.

    One ``grid_sample`` (bilinear, border padding: outside points read the edge) over the samples
    stored as a (1, 1, ny, nx) image: a scan of N x 187 points is one kernel on a GPU where the
    gather-and-blend took 27, and the task asks it three times a step (scan, base, feet)."""

    def __init__(self, grid: TerrainGrid, device: torch.device | str):
        self.device = torch.device(device)
        heights = torch.as_tensor(grid.heights_m, dtype=torch.float32, device=self.device)
        nx, ny = heights.shape
        if min(nx, ny) < 2:
            raise ValueError(f"terrain of {nx} x {ny} samples: bilinear heights need at least 2 along x and y")
        # grid_sample's image is (H, W) = (y, x) and its grid's last axis is (x, y)
        self._image = heights.T.contiguous()[None, None]
        self.heights_m = self._image[0, 0].T
        """(nx, ny) sample heights, m (``TerrainGrid.heights_m``; a view)."""
        self.origin_xy_m = torch.as_tensor(grid.origin_xy_m, dtype=torch.float32, device=self.device)
        self.spacing_m = float(grid.spacing_m)
        # world xy -> grid_sample's [-1, 1] (align_corners: -1 and 1 are the first and last samples)
        extent_m = torch.tensor([nx - 1, ny - 1], dtype=torch.float32, device=self.device) * self.spacing_m
        self._scale = 2.0 / extent_m
        self._offset = -1.0 - self.origin_xy_m * self._scale

    def height_at(self, xy_w: torch.Tensor) -> torch.Tensor:
        """(...) ground heights, m, under the (..., 2) world points ``xy_w`` (bilinear)."""
        uv = torch.addcmul(self._offset, xy_w.float(), self._scale)
        h = torch.nn.functional.grid_sample(self._image, uv.reshape(1, 1, -1, 2), mode="bilinear",
                                            padding_mode="border", align_corners=True)
        return h.reshape(xy_w.shape[:-1])


@dataclass(kw_only=True)
class HeightScanCfg(Checked):
    """A grid of ground-height samples around the base, in the base's heading frame (legged_gym's
    ``measured_points``: x forward, y left, yaw only, so the scan stays level when the base tilts)."""

    length_m: float = 1.6
    """Extent along the heading, m, centred on ``forward_offset_m``."""
    width_m: float = 1.0
    """Extent across the heading, m."""
    resolution_m: float = 0.1
    """Spacing of the samples, m (17 x 11 = 187 points at the defaults, legged_gym's count)."""
    forward_offset_m: float = field(default=0.0, metadata=rule(signed=True))
    """Shift of the grid's centre ahead of the base, m."""
    height_offset_m: float = field(default=0.0, metadata=rule(signed=True))
    """Subtracted from every base-over-ground height (the base's nominal height, so a flat floor
    reads about 0), m."""
    clip_m: float = 1.0
    """Readings are clipped to +-this, m (a pit reads as "deep", not how deep)."""


class HeightScan:
    """Base height over the ground at a grid of points around the base: (N, P) float32, m."""

    def __init__(self, cfg: HeightScanCfg, heights: TerrainHeights):
        self.cfg, self.heights = cfg, heights
        dev = heights.device
        nx = int(round(cfg.length_m / cfg.resolution_m)) + 1
        ny = int(round(cfg.width_m / cfg.resolution_m)) + 1
        x = torch.linspace(-cfg.length_m / 2, cfg.length_m / 2, nx, device=dev) + cfg.forward_offset_m
        y = torch.linspace(-cfg.width_m / 2, cfg.width_m / 2, ny, device=dev)
        gx, gy = torch.meshgrid(x, y, indexing="ij")
        self.points_h = torch.stack([gx.reshape(-1), gy.reshape(-1)], dim=-1)
        """(P, 2) sample points in the heading frame, m."""
        self.num_points = self.points_h.shape[0]
        self._points_c = torch.view_as_complex(self.points_h.contiguous())
        """(P,) complex64 ``x + iy``: a yaw rotation is one complex product (3 kernels where the
        cos/sin terms took 11 on a GPU)."""

    def points_w(self, root_pos_w: torch.Tensor, heading_w: torch.Tensor) -> torch.Tensor:
        """(N, P, 2) world xy of the sample points for bases at ``root_pos_w`` (N, 3) with yaw
        ``heading_w`` (N,) rad."""
        heading = heading_w.float()
        turn = torch.polar(torch.ones_like(heading), heading)  # (N,) e^{i yaw}
        return torch.view_as_real(turn[:, None] * self._points_c) + root_pos_w[:, None, :2].float()

    def scan(self, root_pos_w: torch.Tensor, heading_w: torch.Tensor) -> torch.Tensor:
        """(N, P) ``base z - ground z - height_offset_m`` at each point, clipped, m."""
        ground = self.heights.height_at(self.points_w(root_pos_w, heading_w))
        reading = root_pos_w[:, 2:3].float() - ground - self.cfg.height_offset_m
        return reading.clamp(-self.cfg.clip_m, self.cfg.clip_m)


__all__ = ["HeightScan", "HeightScanCfg", "TerrainHeights"]
