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
    """``height_at(xy)`` for (..., 2) world points, m, as float32 on ``device``."""

    def __init__(self, grid: TerrainGrid, device: torch.device | str):
        self.device = torch.device(device)
        self.heights_m = torch.as_tensor(grid.heights_m, dtype=torch.float32, device=self.device)
        """(nx, ny) sample heights, m (``TerrainGrid.heights_m``)."""
        self.origin_xy_m = torch.as_tensor(grid.origin_xy_m, dtype=torch.float32, device=self.device)
        self.spacing_m = float(grid.spacing_m)
        self._flat = self.heights_m.reshape(-1)
        self._nx, self._ny = self.heights_m.shape

    def height_at(self, xy_w: torch.Tensor) -> torch.Tensor:
        """(...) ground heights, m, under the (..., 2) world points ``xy_w`` (bilinear)."""
        f = (xy_w.float() - self.origin_xy_m) / self.spacing_m
        fx = f[..., 0].clamp(0.0, self._nx - 1.0)
        fy = f[..., 1].clamp(0.0, self._ny - 1.0)
        x0 = fx.floor().clamp(max=self._nx - 2)
        y0 = fy.floor().clamp(max=self._ny - 2)
        tx, ty = fx - x0, fy - y0
        i = x0.long() * self._ny + y0.long()
        h = self._flat
        h00, h01 = h[i], h[i + 1]
        h10, h11 = h[i + self._ny], h[i + self._ny + 1]
        return torch.lerp(torch.lerp(h00, h10, tx), torch.lerp(h01, h11, tx), ty)


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

    def points_w(self, root_pos_w: torch.Tensor, heading_w: torch.Tensor) -> torch.Tensor:
        """(N, P, 2) world xy of the sample points for bases at ``root_pos_w`` (N, 3) with yaw
        ``heading_w`` (N,) rad."""
        c, s = torch.cos(heading_w.float())[:, None], torch.sin(heading_w.float())[:, None]
        px, py = self.points_h[:, 0], self.points_h[:, 1]
        x = root_pos_w[:, 0:1].float() + c * px - s * py
        y = root_pos_w[:, 1:2].float() + s * px + c * py
        return torch.stack([x, y], dim=-1)

    def scan(self, root_pos_w: torch.Tensor, heading_w: torch.Tensor) -> torch.Tensor:
        """(N, P) ``base z - ground z - height_offset_m`` at each point, clipped, m."""
        ground = self.heights.height_at(self.points_w(root_pos_w, heading_w))
        reading = root_pos_w[:, 2:3].float() - ground - self.cfg.height_offset_m
        return reading.clamp(-self.cfg.clip_m, self.cfg.clip_m)


__all__ = ["HeightScan", "HeightScanCfg", "TerrainHeights"]
