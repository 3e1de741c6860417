"""Score an occupancy slice against exact ground truth (``maps.Grid2D``, e.g. ``Apartment.occupancy``):
is the free space that was seen free, and do walls keep their thickness?

- ``VisibleCells``: which truly free cells the camera saw, from the depth images and the true poses
  alone (not from the map): every ray, sampled every ``step_m`` from the camera to a voxel short of
  its hit, marks the cells its samples in the height band fall in.
- ``score_slice``: over the truly free, seen cells, the fractions the slice calls free / unknown /
  occupied (``free_recall`` is the first: the acceptance wants >= 0.95); and the thickness of every
  wall crossing: along each grid row and column, a run of truly occupied cells of at most
  ``max_wall_cells`` with free cells on both sides, both seen free in the slice within
  ``max_wall_cells`` of it: its thickness in the slice is the run of non-free cells that covers it
  (occupied, or unknown inside), and the acceptance wants it within one cell of the truth; a wall
  seen from one side only is measured from that side (``_wall_crossings``). A truly
  occupied cell the slice calls free is a hole (reported, and a wall crossing with one is a failure).

The slice and the truth must share their cells (same resolution, origins a whole number of cells
apart): ``aligned_offset_xy_m`` gives the world shift that puts a TSDF's voxel columns on the truth's
cells (map = world + offset, and the slice's origin less the offset is in the world).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..maps import OCCUPIED as GRID_OCCUPIED
from ..maps import Grid2D
from .frames import RgbdFrame
from .slices import FREE, OCCUPIED, UNKNOWN, Slice2D


def aligned_offset_xy_m(truth: Grid2D, voxel_size_m: float) -> np.ndarray:
    """(3,) world shift (x, y, 0), m, so that a TSDF fused at poses shifted by it has its voxel columns'
    cells (edges at (k - 1/2) voxel in the map) on the cells of ``truth``."""
    if abs(truth.resolution_m - voxel_size_m) > 1e-9:
        raise ValueError(f"the truth's cells are {truth.resolution_m} m and the voxels {voxel_size_m} m: "
                         "score a map whose voxels are the truth's cells")
    ox, oy = truth.origin_xy_m
    return np.array([(-0.5 * voxel_size_m - ox) % voxel_size_m, (-0.5 * voxel_size_m - oy) % voxel_size_m, 0.0])


class VisibleCells:
    """Counts, per cell of ``truth``, the depth-ray samples in the height band [z_min_m, z_max_m] that
    passed through it (``add``); ``mask`` is the cells seen."""

    def __init__(self, truth: Grid2D, z_min_m: float, z_max_m: float, *, pixel_stride: int = 4,
                 step_m: float = 0.025, depth_min_m: float = 0.1, depth_max_m: float = 5.0):
        self.truth, self.z = truth, (z_min_m, z_max_m)
        self.pixel_stride, self.step_m, self.depth = pixel_stride, step_m, (depth_min_m, depth_max_m)
        self.count = np.zeros(truth.shape, np.int64)

    def add(self, frame: RgbdFrame) -> None:
        """The rays of every ``pixel_stride``-th pixel with a valid depth, at the frame's (true) pose."""
        s = self.pixel_stride
        depth = frame.depth_m.numpy()[::s, ::s].astype(np.float64)
        k = frame.intrinsics.numpy()
        h, w = frame.depth_m.shape
        v, u = np.mgrid[0:h:s, 0:w:s].astype(np.float64)
        ok = np.isfinite(depth) & (depth >= self.depth[0]) & (depth <= self.depth[1])
        rays = np.stack([(u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1], np.ones_like(u)], -1)[ok]  # z = 1
        d = depth[ok]
        pose = frame.pose_wc.numpy()
        dirs = rays @ pose[:3, :3].T
        t = np.arange(0.0, float(d.max(initial=0.0)), self.step_m)
        # stop a voxel (0.05 m) short of the hit along the ray, so the sample is in front of the surface
        stop = d - 0.05 / np.linalg.norm(rays, axis=1)
        pts = pose[:3, 3] + dirs[:, None, :] * t[None, :, None]  # (R, T, 3)
        keep = (t[None, :] < stop[:, None]) & (pts[..., 2] >= self.z[0]) & (pts[..., 2] <= self.z[1])
        iy, ix = self.truth.cells_of(pts[keep][:, :2])
        inside = (iy >= 0) & (iy < self.count.shape[0]) & (ix >= 0) & (ix < self.count.shape[1])
        np.add.at(self.count, (iy[inside], ix[inside]), 1)

    @property
    def mask(self) -> np.ndarray:
        """(H, W) bool cells some ray sample of the band passed through."""
        return self.count > 0


@dataclass
class SliceScore:
    free_recall: float
    """Of the truly free cells seen (``VisibleCells``), the fraction the slice calls free."""
    free_unknown: float
    """... the fraction it calls unknown (free space not carved)."""
    free_occupied: float
    """... the fraction it calls occupied (false obstacles)."""
    seen_free_cells: int
    wall_crossings: int
    """Wall crossings measured (both sides seen free in the slice)."""
    walls_within_one_cell: float
    """Fraction of them whose thickness in the slice is within one cell of the truth (no hole in them)."""
    wall_excess_cells_median: float
    """Median of (slice thickness - true thickness) over the crossings, cells."""
    wall_excess_cells_max: int
    holes: int
    """Truly occupied cells the slice calls free."""
    occupied_beyond_one_cell: float
    """Of the cells the slice calls occupied, the fraction more than one cell (8-neighbourhood) from any
    truly occupied cell: walls grown by more than a cell, or obstacles that are not there."""

    def as_dict(self) -> dict:
        return {k: round(v, 4) if isinstance(v, float) else v for k, v in self.__dict__.items()}


def slice_on_cells(sl: Slice2D, truth: Grid2D, offset_xy_m=(0.0, 0.0)) -> np.ndarray:
    """(H, W) int8 the slice's codes on ``truth``'s cells (UNKNOWN outside the slice); ``offset_xy_m``:
    the world shift the map was fused with (``aligned_offset_xy_m``)."""
    ox = (sl.origin_xy_m[0] - offset_xy_m[0] - truth.origin_xy_m[0]) / truth.resolution_m
    oy = (sl.origin_xy_m[1] - offset_xy_m[1] - truth.origin_xy_m[1]) / truth.resolution_m
    cx, cy = int(round(ox)), int(round(oy))
    if abs(ox - cx) > 1e-3 or abs(oy - cy) > 1e-3 or abs(sl.resolution_m - truth.resolution_m) > 1e-9:
        raise ValueError("the slice's cells are not the truth's: fuse the map at poses shifted by "
                         "aligned_offset_xy_m(truth, voxel_size_m) and pass that offset")
    out = np.full(truth.shape, UNKNOWN, np.int8)
    data = sl.data.cpu().numpy()
    ny, nx = truth.shape
    y0, x0 = max(cy, 0), max(cx, 0)
    y1, x1 = min(cy + data.shape[0], ny), min(cx + data.shape[1], nx)
    if y1 > y0 and x1 > x0:
        out[y0:y1, x0:x1] = data[y0 - cy:y1 - cy, x0 - cx:x1 - cx]
    return out


def score_slice(pred: np.ndarray, truth: Grid2D, visible: np.ndarray, max_wall_cells: int = 6,
                walls: np.ndarray | None = None) -> SliceScore:
    """``pred``: (H, W) slice codes on the truth's cells (``slice_on_cells``); ``visible``: (H, W) bool
    cells the camera saw (``VisibleCells.mask``); ``walls``: (H, W) bool the walls' own cells, if only
    their crossings are to be measured (not furniture's). See the module doc."""
    occ = truth.occupancy >= GRID_OCCUPIED
    seen_free = ~occ & visible
    n = int(seen_free.sum())
    frac = (lambda code: float((pred[seen_free] == code).sum()) / n) if n else (lambda code: float("nan"))
    excess, ok = [], []
    wall = occ if walls is None else walls
    for grid_occ, grid_pred, grid_vis, grid_wall in ((occ, pred, visible, wall), (occ.T, pred.T, visible.T, wall.T)):
        for row_occ, row_pred, row_vis, row_wall in zip(grid_occ, grid_pred, grid_vis, grid_wall):
            _wall_crossings(row_occ, row_pred, row_vis, row_wall, max_wall_cells, excess, ok)
    excess_arr = np.array(excess, float)
    return SliceScore(
        free_recall=frac(FREE), free_unknown=frac(UNKNOWN), free_occupied=frac(OCCUPIED), seen_free_cells=n,
        wall_crossings=len(ok), walls_within_one_cell=float(np.mean(ok)) if ok else float("nan"),
        wall_excess_cells_median=float(np.median(excess_arr[np.isfinite(excess_arr)])) if len(excess_arr) else float("nan"),
        wall_excess_cells_max=int(np.nanmax(np.where(np.isfinite(excess_arr), excess_arr, np.nan))) if len(excess_arr)
        and np.isfinite(excess_arr).any() else 0,
        holes=int((occ & (pred == FREE)).sum()), occupied_beyond_one_cell=_beyond_one_cell(pred == OCCUPIED, occ))


def _beyond_one_cell(claimed: np.ndarray, occ: np.ndarray) -> float:
    near = occ.copy()
    padded = np.pad(occ, 1)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near |= padded[1 + dy:1 + dy + occ.shape[0], 1 + dx:1 + dx + occ.shape[1]]
    n = int(claimed.sum())
    return float((claimed & ~near).sum()) / n if n else 0.0


def _wall_crossings(row_occ: np.ndarray, row_pred: np.ndarray, row_visible: np.ndarray, row_wall: np.ndarray,
                    max_cells: int, excess: list, ok: list) -> None:
    """Append each crossing's (slice - true) thickness (inf for a hole) and whether it is within one cell.

    Seen from both sides (both free neighbours seen, and the slice free on both sides within
    ``max_cells``): the slice's thickness is its run of non-free cells over the wall (unknown inside
    counts). Seen from one side: the far face is unknown, so only the occupied run from the seen side
    is measured, and it must be at least one cell and at most the truth's thickness + 1 (the fault
    this catches: the truncation band behind a face counted occupied, 4 cells more)."""
    n = len(row_occ)
    i = 0
    while i < n:
        if not row_occ[i]:
            i += 1
            continue
        j = i
        while j + 1 < n and row_occ[j + 1]:
            j += 1
        a, b = i, j  # truly occupied run [a, b]
        i = j + 1
        true = b - a + 1
        if a == 0 or b == n - 1 or true > max_cells or not row_wall[a:b + 1].all():
            continue  # not (only) a wall
        seen_left, seen_right = bool(row_visible[a - 1]), bool(row_visible[b + 1])
        if not (seen_left or seen_right):
            continue
        left = a - 1  # the slice's non-free cells reaching out of the run on either side
        while left >= 0 and row_pred[left] != FREE and a - left <= max_cells:
            left -= 1
        right = b + 1
        while right < n and row_pred[right] != FREE and right - b <= max_cells:
            right += 1
        both = (seen_left and seen_right and left >= 0 and right < n and row_pred[left] == FREE
                and row_pred[right] == FREE)
        if both and not (row_pred[a:b + 1] == FREE).any():
            extra = (right - left - 1) - true
            excess.append(float(extra))
            ok.append(abs(extra) <= 1)
            continue
        # one side: the occupied cells from the first non-free cell of the seen side on
        start, step = (left + 1, 1) if seen_left else (right - 1, -1)
        if not 0 <= start < n or row_pred[start] == FREE:
            excess.append(float("inf"))  # nothing where the seen face is: a hole
            ok.append(False)
            continue
        k = start
        count = 0
        while 0 <= k < n and row_pred[k] == OCCUPIED:
            count += 1
            k += step
        if count == 0 and row_pred[start] == UNKNOWN:
            continue  # the face itself unknown (seen too obliquely): nothing to measure
        extra = count - true
        excess.append(float(extra))
        ok.append(1 <= count <= true + 1)


__all__ = ["SliceScore", "VisibleCells", "aligned_offset_xy_m", "score_slice", "slice_on_cells"]
