"""Sub-terrain height functions: one square tile's heights (m) on its sample grid, by difficulty.

Each function takes the tile's sample grid and a difficulty ``d`` in [0, 1] (0 the easiest level,
1 the hardest) and returns an ``(n, n)`` float64 array of heights, indexed ``[ix, iy]`` (x first).
Samples sit at ``ix * h`` from the tile's corner, ``h`` the grid spacing. Shapes are computed on
integer sample indices, so a stair edge or a stone falls on the same sample whatever the floats
(a tread of 0.30 m at 0.05 m spacing is exactly 6 samples).

Pyramids (slopes, stairs) are measured from the tile's edge inwards by the Chebyshev distance
``e = min(ix, n - ix, iy, n - iy) * h`` (the edge ring is at height 0, so neighbouring tiles meet
without a step), up to the flat centre platform where the robots start. "Up" and "down" name what
a robot walking out of the centre does: on ``stairs_up`` the centre is a pit and the rings rise
outwards, on ``stairs_down`` the centre is a summit. The shapes follow legged_gym's
``terrain_utils`` (pyramid slopes, pyramid stairs, random uniform, stepping stones), written here
from their descriptions, with humanoid-sized defaults (``TerrainCfg``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TileGrid:
    """A tile's sample grid: ``num`` samples per side at ``spacing_m``; ``platform`` samples of
    the flat centre (its half-width, counted from the centre)."""

    num: int
    spacing_m: float
    platform_half: int

    def edge_distance(self) -> np.ndarray:
        """(n, n) int: samples from the tile's nearest edge (Chebyshev), 0 on the edge ring."""
        i = np.arange(self.num)
        ex = np.minimum(i, self.num - i)
        return np.minimum(ex[:, None], ex[None, :])

    def ramp(self) -> int:
        """Samples from the edge to the platform: where pyramids stop rising."""
        return max(self.num // 2 - self.platform_half, 0)


def lerp(bounds: tuple[float, float], d: float) -> float:
    return float(bounds[0] + (bounds[1] - bounds[0]) * d)


def flat(grid: TileGrid, d: float, cfg, rng: np.random.Generator) -> np.ndarray:
    del d, cfg, rng
    return np.zeros((grid.num, grid.num))


def _slope(grid: TileGrid, d: float, cfg, sign: float) -> np.ndarray:
    grade = lerp(cfg.slope_grade_range, d)  # rise per run (tan of the slope angle)
    e = np.minimum(grid.edge_distance(), grid.ramp()) * grid.spacing_m
    return sign * grade * e


def slope_up(grid, d, cfg, rng):
    """A pyramid pit: the ground rises ``slope_grade`` per metre from the centre out."""
    del rng
    return _slope(grid, d, cfg, -1.0)


def slope_down(grid, d, cfg, rng):
    """A pyramid: the ground falls ``slope_grade`` per metre from the centre out."""
    del rng
    return _slope(grid, d, cfg, 1.0)


def stair_count(grid: TileGrid, tread_samples: int) -> int:
    """Whole steps between the edge ring and the platform."""
    return grid.ramp() // tread_samples


def _stairs(grid: TileGrid, d: float, cfg, sign: float) -> np.ndarray:
    riser = lerp(cfg.stair_riser_range_m, d)
    tread = tread_samples(cfg, grid.spacing_m)
    steps = np.minimum(grid.edge_distance() // tread, stair_count(grid, tread))
    return sign * riser * steps


def tread_samples(cfg, spacing_m: float) -> int:
    return max(int(round(cfg.stair_tread_m / spacing_m)), 1)


def stairs_up(grid, d, cfg, rng):
    """Pyramid stairs around a pit: step ``k`` from the edge is ``-k * riser`` (walking out climbs)."""
    del rng
    return _stairs(grid, d, cfg, -1.0)


def stairs_down(grid, d, cfg, rng):
    """Pyramid stairs around a summit: step ``k`` from the edge is ``+k * riser``."""
    del rng
    return _stairs(grid, d, cfg, 1.0)


def rough(grid: TileGrid, d: float, cfg, rng: np.random.Generator) -> np.ndarray:
    """Uniform random heights in +-``rough_amplitude`` drawn every ``rough_cell_m`` and bilinearly
    interpolated between (a random value per sample would be a bed of needles at 5 cm), with the
    centre platform flat."""
    amplitude = lerp(cfg.rough_amplitude_range_m, d)
    step = max(int(round(cfg.rough_cell_m / grid.spacing_m)), 1)
    coarse_n = grid.num // step + 2
    coarse = rng.uniform(-amplitude, amplitude, size=(coarse_n, coarse_n))
    t = np.arange(grid.num) / step
    i0 = np.floor(t).astype(int)
    f = t - i0
    along_x = coarse[i0] * (1 - f)[:, None] + coarse[i0 + 1] * f[:, None]
    heights = along_x[:, i0] * (1 - f)[None, :] + along_x[:, i0 + 1] * f[None, :]
    heights[grid.edge_distance() > grid.ramp()] = 0.0
    return heights


def stepping_stones(grid: TileGrid, d: float, cfg, rng: np.random.Generator) -> np.ndarray:
    """Square stones at height 0 with gaps down to ``-stone_pit_depth_m`` around the flat centre:
    stones shrink and gaps widen with difficulty. The stone lattice starts at the tile's corner
    with a random offset of up to one period, so the gaps are not the same in every column."""
    size = max(int(round(lerp(cfg.stone_edge_m, d) / grid.spacing_m)), 1)
    gap = max(int(round(lerp(cfg.stone_gap_range_m, d) / grid.spacing_m)), 0)
    period = size + gap
    offset = rng.integers(0, period, size=2)
    i = np.arange(grid.num)
    on_x = (i + offset[0]) % period < size
    on_y = (i + offset[1]) % period < size
    heights = np.where(on_x[:, None] & on_y[None, :], 0.0, -cfg.stone_pit_depth_m)
    heights[grid.edge_distance() > grid.ramp()] = 0.0
    return heights


KINDS = {"flat": flat, "slope_up": slope_up, "slope_down": slope_down, "rough": rough,
         "stairs_up": stairs_up, "stairs_down": stairs_down, "stepping_stones": stepping_stones}
"""Sub-terrain kind -> height function ``f(grid, difficulty, cfg, rng) -> (n, n) heights``."""

__all__ = ["KINDS", "TileGrid", "flat", "lerp", "rough", "slope_down", "slope_up", "stair_count",
           "stairs_down", "stairs_up", "stepping_stones", "tread_samples"]
