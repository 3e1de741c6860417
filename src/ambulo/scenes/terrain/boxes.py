"""Piecewise-flat tiles (flat, stairs, the border; stepping stones on request) as static boxes; the
heightfield keeps the rest.

Why: MuJoCo C collides a sphere with a heightfield prism by prism, so a sole sphere resting on a
flat hfield gets one contact per prism it overlaps (up to 3 on one sphere: 9 contacts on 4 sole
spheres, against MuJoCo Warp's 8, one per sphere). A humanoid-footsteps-stairs policy trained on
MuJoCo Warp fell in 9 of 16 episodes on flat tiles on MuJoCo C (0 on Warp); the same tiles as a
plane: 0 of 32 (21 of 32 on the hfield). A sphere on a box is one analytic contact in both
engines. Rough ground and slopes are not piecewise flat and stay in the hfield. Which kinds are
boxes is ``TerrainCfg.box_kinds`` (default ``BOX_KINDS``; stepping stones, also piecewise flat, can
join: a stone is a rectangle of the height-0 slab over a box for the pit's floor).

The boxes reproduce ``TerrainGrid.heights_m``, which stays the one truth for height scans,
spawning and planners: sample ``(ix, iy)`` owns the square of one spacing centred on it, so a
box's top equals the samples it covers and a stair edge is a vertical face half-way between the
two samples of different height (the hfield's edge is a ramp over that cell; ``height_at`` is
bilinear over it, as before). Height 0 (the border, flat tiles, every tile's edge ring) is one
slab of rectangles over the whole grid; then per tile each other distinct height ``L`` gets the
rectangles of ``{samples >= L}``, tops at ``L`` and all reaching the tile's floor: a summit
(``stairs_down``) is a stack of squares, one box a step; a pit (``stairs_up``) a frame of four
boxes a step; a stepping-stone tile one box at the pit's depth under the whole tile. The slab
reaches down to every box tile's next level below 0 (at least ``FLOOR_DEPTH_M``), so no gap opens
under a stone when the pit is deeper. The boxes overlap below their tops, which no sphere reaches. Where two coplanar
tops meet (the slab's rectangles, a pit ring's corners) a sphere within a few mm of the seam also
touches the neighbour's edge (a second, shallower contact, alike in both engines).

The hfield stays one geom (the other tiles, and the terrain body the contact sensor reads): its
samples strictly inside the boxes (all 8 neighbours under boxes too) sink ``SUNK_M`` below the
lowest height, so no foot on a box touches it; samples on a seam with an hfield tile keep their
height, so the hfield's surface between two tiles is unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.ndimage import binary_erosion

if TYPE_CHECKING:
    from .generator import TerrainGrid

BOX_KINDS = ("flat", "stairs_up", "stairs_down")
"""The kinds built as boxes by default (``TerrainCfg.box_kinds``): those of session 15."""

PIECEWISE_FLAT_KINDS = (*BOX_KINDS, "stepping_stones")
"""Sub-terrain kinds whose surface is piecewise flat, so boxes can build them exactly (rough ground
and slopes cannot)."""

FLOOR_DEPTH_M = 0.5
"""Boxes reach this far below their region's lowest height, m (a floor no contact goes through)."""

SUNK_M = 0.5
"""Hfield samples under boxes sit this far below the terrain's lowest height, m."""


@dataclass(frozen=True)
class TerrainBoxes:
    """Static boxes of the terrain, world frame.

    Attributes:
      center_w: (B, 3) float64 box centres, m.
      half_size_m: (B, 3) float64 half extents along world x, y, z, m.
      mask: (nx, ny) bool, samples covered by boxes.
    """

    center_w: np.ndarray
    half_size_m: np.ndarray
    mask: np.ndarray

    @property
    def top_m(self) -> np.ndarray:
        """(B,) heights of the boxes' top faces, m."""
        return self.center_w[:, 2] + self.half_size_m[:, 2]


def rectangles(mask: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Disjoint rectangles ``(ix, iy, lx, ly)`` covering the True cells of a 2-D ``mask`` exactly:
    greedy, each one as long along y and then along x as the cells allow (a frame gives 4)."""
    left = mask.copy()
    out = []
    while left.any():
        ix, iy = np.unravel_index(int(left.argmax()), left.shape)  # first True, row-major
        row = left[ix, iy:]
        ly = int(row.argmin()) if not row.all() else row.size
        rows = left[ix:, iy:iy + ly].all(axis=1)
        lx = int(rows.argmin()) if not rows.all() else rows.size
        out.append((int(ix), int(iy), lx, ly))
        left[ix:ix + lx, iy:iy + ly] = False
    return out


def _stack(heights: np.ndarray, skip: float) -> list[tuple]:
    """``(ix, iy, lx, ly, top, bottom)`` boxes of a tile's ``heights``: for each distinct height but
    ``skip``, the rectangles of the samples at least that high, reaching ``FLOOR_DEPTH_M`` below the
    lowest."""
    levels = np.unique(heights)
    floor = float(levels[0]) - FLOOR_DEPTH_M
    return [(ix, iy, lx, ly, float(top), floor)
            for top in levels if top != skip for ix, iy, lx, ly in rectangles(heights >= top)]


def box_mask(grid: TerrainGrid) -> np.ndarray:
    """(nx, ny) bool: the samples of box tiles (``TerrainCfg.box_kinds``) and of the border."""
    cfg = grid.cfg
    mask = np.ones(grid.heights_m.shape, dtype=bool)
    for j, kind in enumerate(cfg.kinds):
        if kind not in cfg.box_kinds:
            for i in range(cfg.num_levels):
                mask[cfg.tile_slices(i, j)] = False
    return mask


def terrain_boxes(grid: TerrainGrid) -> TerrainBoxes:
    """The boxes of ``grid``'s box tiles and border (see the module docstring)."""
    cfg, h, heights = grid.cfg, grid.spacing_m, grid.heights_m
    mask = box_mask(grid)
    tiles, slab_bottom = [], -FLOOR_DEPTH_M
    for i in range(cfg.num_levels):
        for j, kind in enumerate(cfg.kinds):
            if kind in cfg.box_kinds:
                xs, ys = cfg.tile_slices(i, j)
                tile = heights[xs, ys]
                tiles += [(xs.start + ix, ys.start + iy, lx, ly, top, bottom) for ix, iy, lx, ly, top, bottom
                          in _stack(tile, skip=0.0)]
                below = tile[tile < 0.0]  # the next level down's box covers the tile's height-0 samples
                slab_bottom = min(slab_bottom, float(below.max())) if below.size else slab_bottom
    # height 0 (the border, flat tiles, every tile's edge ring, a summit's foot, the stones) over
    # the whole grid at once: coplanar boxes side by side leave a seam where a sphere within a few
    # mm of it touches the neighbour's edge too, and one slab over many tiles has few seams
    slab = [(ix, iy, lx, ly, 0.0, slab_bottom) for ix, iy, lx, ly in rectangles(mask & (heights >= 0.0))]
    b = np.array(slab + tiles, dtype=np.float64).reshape(-1, 6)
    ix, iy, lx, ly, top, bottom = b.T
    # sample i owns [i - 1/2, i + 1/2) spacings from the origin
    center = np.stack([grid.origin_xy_m[0] + (ix + lx / 2 - 0.5) * h, grid.origin_xy_m[1] + (iy + ly / 2 - 0.5) * h,
                       (top + bottom) / 2], axis=-1)
    half = np.stack([lx * h / 2, ly * h / 2, (top - bottom) / 2], axis=-1)
    return TerrainBoxes(center, half, mask)


def hfield_heights(grid: TerrainGrid, mask: np.ndarray) -> np.ndarray:
    """(nx, ny) heights for the physics hfield: ``grid.heights_m`` with the samples strictly inside
    ``mask`` (all 8 neighbours in it too; the grid's outside counts as in) sunk ``SUNK_M`` below
    the lowest height."""
    inside = binary_erosion(mask, np.ones((3, 3), dtype=bool), border_value=1)
    heights = grid.heights_m.copy()
    heights[inside] = float(grid.heights_m.min()) - SUNK_M
    return heights


__all__ = ["BOX_KINDS", "FLOOR_DEPTH_M", "PIECEWISE_FLAT_KINDS", "SUNK_M", "TerrainBoxes", "box_mask", "hfield_heights", "rectangles",
           "terrain_boxes"]
