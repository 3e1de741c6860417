"""A 2-D occupancy grid with an optional height map, and the grid geometry the footstep planner
builds on: a geodesic distance field (``chamfer_distance_m``), a dilation by a distance
(``near_occupied``) and the exact cells a segment crosses (``crossed_cells``). All are array
operations, with no Python loop per cell.

Cells follow ``ambulo.maps`` (``CellGeometry``, ROS's convention): cell ``[iy, ix]`` covers world
``x`` in ``[ox + ix r, ox + (ix + 1) r)`` and ``y`` in ``[oy + iy r, oy + (iy + 1) r)``, where
``(ox, oy) = origin_xy_m`` is the map's lower-left corner and ``r = resolution_m``; arrays are
indexed row = y, column = x (y up). A ``maps.Grid2D`` (a map file) becomes a ``GridMap`` with
``GridMap.from_map``, its unknown cells blocked. The planner treats everything outside the map as
occupied.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from ..maps import OCCUPIED, CellGeometry, Grid2D
from ..utils.checks import InvalidValueError, check_positive, check_vector

CHAMFER_AXIAL = 5
"""Integer cost of a move to a side neighbour in ``chamfer_distance_m`` (one cell)."""
CHAMFER_DIAGONAL = 7
"""Integer cost of a diagonal move: 7/5 = 1.4 < sqrt(2), so a diagonal never costs more than
its Euclidean length; the 5-7 metric exceeds the Euclidean one by at most ``CHAMFER_MAX_RATIO``."""
CHAMFER_MAX_RATIO = math.hypot(CHAMFER_AXIAL, CHAMFER_DIAGONAL - CHAMFER_AXIAL) / CHAMFER_AXIAL
"""max over directions of (5-7 chamfer length) / (Euclidean length) = sqrt(29) / 5 = 1.0770, reached
at direction (1, 2/5): maximize (5 + 2t) / (5 sqrt(1 + t^2)) over t in [0, 1]."""


@dataclass(frozen=True, eq=False)
class GridMap(CellGeometry):
    """Occupancy (and optionally terrain height) on a regular grid in the world x-y plane."""

    occupied: np.ndarray
    """(num_y, num_x) bool; True where a cell holds an obstacle the robot may neither stand on
    nor swing a foot over (walls, furniture)."""
    origin_xy_m: tuple[float, float]
    """World (x, y) of the lower-left corner of cell [0, 0], m."""
    resolution_m: float
    """Side of a square cell, m."""
    height_m: np.ndarray | None = None
    """(num_y, num_x) float terrain height (world z) of each cell, m; None for flat ground at z = 0."""

    def __post_init__(self) -> None:
        if not isinstance(self.occupied, np.ndarray) or self.occupied.ndim != 2 or self.occupied.dtype != bool:
            raise InvalidValueError("GridMap.occupied", type(self.occupied).__name__,
                                    "expected a 2-D numpy bool array (num_y, num_x)",
                                    "build maps with GridMap.from_array, which converts torch/numpy input")
        check_vector("GridMap.origin_xy_m", self.origin_xy_m, 2, "pass the map corner as (x, y) in m")
        check_positive("GridMap.resolution_m", self.resolution_m, "pass the cell size in m, e.g. 0.05")
        if self.height_m is not None:
            if not isinstance(self.height_m, np.ndarray) or self.height_m.shape != self.occupied.shape:
                raise InvalidValueError("GridMap.height_m", getattr(self.height_m, "shape", self.height_m),
                                        f"expected a float array of the occupancy's shape {self.occupied.shape}",
                                        "pass None for flat ground or one height per cell in m")
            if not np.isfinite(self.height_m).all():
                raise InvalidValueError("GridMap.height_m", "an array with NaN/inf", "heights must be finite",
                                        "mark unknown cells as occupied instead")

    @classmethod
    def from_array(cls, occupied, *, origin_xy_m=(0.0, 0.0), resolution_m: float,
                   height_m=None) -> GridMap:
        """A map from (num_y, num_x) occupancy (numpy or torch, bool or 0/1) and optional heights, m."""
        def to_numpy(a):
            return a.detach().cpu().numpy() if isinstance(a, torch.Tensor) else np.asarray(a)
        occ = to_numpy(occupied)
        if occ.ndim != 2:
            raise InvalidValueError("occupied", occ.shape, "expected a 2-D (num_y, num_x) array",
                                    "pass one row per y cell, one column per x cell")
        heights = None if height_m is None else to_numpy(height_m).astype(np.float64)
        return cls(occupied=occ.astype(bool), origin_xy_m=tuple(float(v) for v in origin_xy_m),
                   resolution_m=float(resolution_m), height_m=heights)

    @classmethod
    def from_map(cls, grid: Grid2D, *, min_percent: int = OCCUPIED) -> GridMap:
        """The footstep planner's view of a map file's ``Grid2D``: a cell is occupied where the map
        says occupied (occupancy >= ``min_percent``) or unknown, since a foot must not land on, or
        swing over, ground nobody has seen."""
        return cls(occupied=grid.blocked(min_percent), origin_xy_m=tuple(float(v) for v in grid.origin_xy_m),
                   resolution_m=float(grid.resolution_m))

    @classmethod
    def empty(cls, size_xy_m, *, resolution_m: float, origin_xy_m=(0.0, 0.0), with_height: bool = False) -> GridMap:
        """A free map covering ``size_xy_m`` (x, y) m from ``origin_xy_m``; flat heights (0 m) if asked."""
        size = check_vector("size_xy_m", size_xy_m, 2, "pass the map's (x, y) extent in m")
        check_positive("resolution_m", resolution_m, "pass the cell size in m, e.g. 0.05")
        num_x, num_y = (max(1, math.ceil(s / resolution_m - 1e-9)) for s in size)
        heights = np.zeros((num_y, num_x)) if with_height else None
        return cls(occupied=np.zeros((num_y, num_x), bool), origin_xy_m=tuple(float(v) for v in origin_xy_m),
                   resolution_m=float(resolution_m), height_m=heights)

    @property
    def shape(self) -> tuple[int, int]:
        """(num_y, num_x)."""
        return self.occupied.shape

    def box_cells(self, center_xy_m, size_xy_m, yaw_rad: float = 0.0) -> np.ndarray:
        """(num_y, num_x) bool: the cells whose closed square touches the rotated box (exact
        separating-axis test, so the cells cover the box with nothing missed)."""
        cx, cy = check_vector("center_xy_m", center_xy_m, 2, "pass the box centre (x, y) in m")
        sx, sy = check_vector("size_xy_m", size_xy_m, 2, "pass the box's full (x, y) size in m")
        c, s = math.cos(yaw_rad), math.sin(yaw_rad)
        half_r = 0.5 * self.resolution_m
        d = self.cell_centers_xy_m() - (cx, cy)
        ax, ay = 0.5 * sx, 0.5 * sy
        hit = np.abs(d[..., 0]) <= half_r + ax * abs(c) + ay * abs(s)
        hit &= np.abs(d[..., 1]) <= half_r + ax * abs(s) + ay * abs(c)
        hit &= np.abs(d[..., 0] * c + d[..., 1] * s) <= ax + half_r * (abs(c) + abs(s))
        hit &= np.abs(-d[..., 0] * s + d[..., 1] * c) <= ay + half_r * (abs(c) + abs(s))
        return hit

    def add_box(self, center_xy_m, size_xy_m, yaw_rad: float = 0.0, *, height_m: float | None = None) -> None:
        """Mark a rotated box as an obstacle or, with ``height_m``, raise the terrain under it
        to that height (a platform or stair tread; needs a map with heights)."""
        cells = self.box_cells(center_xy_m, size_xy_m, yaw_rad)
        if height_m is None:
            self.occupied[cells] = True
        elif self.height_m is None:
            raise InvalidValueError("height_m", height_m, "this map has no height layer",
                                    "build it with GridMap.empty(..., with_height=True)")
        else:
            self.height_m[cells] = float(height_m)


def chamfer_distance_m(free: np.ndarray, seeds: np.ndarray, resolution_m: float,
                       entry_cost: np.ndarray | None = None) -> np.ndarray:
    """(num_y, num_x) float: the shortest 8-connected path length from any ``seeds`` cell through
    ``free`` cells, m, with side moves costing one cell and diagonal moves 1.4 cells (the 5-7
    chamfer metric); ``inf`` where no path exists. Diagonal moves between two free cells are
    allowed whatever the two cells beside them hold (a relaxation, so never longer than a
    continuous path's cells allow). ``entry_cost`` (num_y, num_x) int, optional, adds that many
    fifths of a cell to every move into a cell (an inflation cost keeping paths off obstacles);
    the result is then a cost, not a length.

    Exact Dijkstra, vectorized by distance window (Delta-stepping with Delta = the cheapest move):
    no cell whose distance lies in [lo, lo + 5) can improve another in the same window, so the
    whole window is relaxed at once with array operations.
    """
    num_y, num_x = free.shape
    width = num_x + 2
    free_flat = np.zeros((num_y + 2, width), bool)  # one blocked border row/column: no bounds checks
    free_flat[1:-1, 1:-1] = free
    free_flat = free_flat.ravel()
    seed_flat = np.zeros((num_y + 2, width), bool)
    seed_flat[1:-1, 1:-1] = seeds
    offsets = np.array([1, -1, width, -width, width + 1, width - 1, -width + 1, -width - 1])
    costs = np.array([CHAMFER_AXIAL] * 4 + [CHAMFER_DIAGONAL] * 4, np.int32)
    entry = None
    if entry_cost is not None:
        entry = np.zeros((num_y + 2, width), np.int32)
        entry[1:-1, 1:-1] = entry_cost
        entry = entry.ravel()
    unreached = np.iinfo(np.int32).max
    dist = np.full(free_flat.size, unreached, np.int32)
    pending = np.flatnonzero(seed_flat.ravel() & free_flat)
    pending_d = np.zeros(pending.size, np.int32)
    dist[pending] = 0
    claim = np.empty(free_flat.size, np.intp)
    lo = 0
    while pending.size:
        window = pending_d < lo + CHAMFER_AXIAL
        if not window.any():
            lo = int(pending_d.min())
            continue
        cells, cells_d = pending[window], pending_d[window]
        pending, pending_d = pending[~window], pending_d[~window]
        final = dist[cells] == cells_d  # drop entries superseded by a shorter path
        cells, cells_d = cells[final], cells_d[final]
        nbr = (cells[:, None] + offsets).ravel()
        nbr_d = (cells_d[:, None] + costs).ravel()
        if entry is not None:
            nbr_d += entry[nbr]
        better = free_flat[nbr] & (nbr_d < dist[nbr])
        nbr, nbr_d = nbr[better], nbr_d[better]
        np.minimum.at(dist, nbr, nbr_d)
        won = dist[nbr] == nbr_d
        # one entry per cell: of equal winners the last written claims it (no duplicates pending)
        order = np.arange(len(nbr))
        claim[nbr[won]] = order[won]
        won &= claim[nbr] == order
        pending = np.concatenate([pending, nbr[won]])
        pending_d = np.concatenate([pending_d, nbr_d[won]])
        lo += CHAMFER_AXIAL
    out = dist.reshape(num_y + 2, width)[1:-1, 1:-1].astype(np.float64) * (resolution_m / CHAMFER_AXIAL)
    out[dist.reshape(num_y + 2, width)[1:-1, 1:-1] == unreached] = np.inf
    return out


def near_occupied(occupied: np.ndarray, resolution_m: float, radius_m: float, *, from_cell_centers: bool) -> np.ndarray:
    """(num_y, num_x) bool: cells that come closer than ``radius_m`` to an occupied cell (and the
    occupied cells themselves). The distance is measured from the whole cell (any point of it) or,
    with ``from_cell_centers``, from its centre, to the nearest point of an occupied cell. Off the
    map counts as free here. Exact for that metric: a dilation by the set of cell offsets within
    reach, one shifted OR per offset."""
    reach = radius_m / resolution_m
    shrink = 0.5 if from_cell_centers else 1.0  # gap between the two cells along one axis, in cells
    span = max(0, math.ceil(reach + shrink))
    out = occupied.copy()
    if reach <= 0:
        return out
    num_y, num_x = occupied.shape
    for di in range(-span, span + 1):
        for dj in range(-span, span + 1):
            gap = math.hypot(max(abs(di) - shrink, 0.0), max(abs(dj) - shrink, 0.0))
            if (di or dj) and gap < reach:
                out[max(0, -di):num_y - max(0, di), max(0, -dj):num_x - max(0, dj)] |= \
                    occupied[max(0, di):num_y - max(0, -di), max(0, dj):num_x - max(0, -dj)]
    return out


def crossed_cells(u0, v0, u1, v1, max_lines: int) -> tuple[np.ndarray, np.ndarray]:
    """Every cell that K segments cross, exactly (the segments' supercover), as one point inside
    each: ``(u, v)`` of shape (K, 2 max_lines + 1), in cell units (world / resolution, so cell
    [iv, iu] = [floor(v), floor(u)]). The segments run from (u0, v0) to (u1, v1) ((K,) each, or
    scalars for the start); none may cross more than ``max_lines`` grid lines along one axis
    (floor(length / resolution) + 1 is enough). A cell can appear more than once.

    The crossings with the grid lines split each segment into pieces inside one cell each; the
    midpoint of every piece (in the sorted order of the crossing parameters) lies in its cell."""
    u0, v0, u1, v1 = (np.asarray(a, float) for a in (u0, v0, u1, v1))
    du, dv = u1 - u0, v1 - v0
    steps = np.arange(1, max_lines + 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        lines_u = np.floor(np.minimum(u0, u1))[..., None] + steps
        t_u = (lines_u - u0[..., None]) / du[..., None]
        lines_v = np.floor(np.minimum(v0, v1))[..., None] + steps
        t_v = (lines_v - v0[..., None]) / dv[..., None]
    t = np.concatenate([np.zeros_like(t_u[..., :1]), t_u, t_v], axis=-1)
    t = np.sort(np.where((t >= 0) & (t <= 1), t, 1.0), axis=-1)  # off-segment and 0/0: the end
    mid = np.concatenate([0.5 * (t[..., :-1] + t[..., 1:]), t[..., -1:]], axis=-1)
    return u0[..., None] + du[..., None] * mid, v0[..., None] + dv[..., None] * mid
