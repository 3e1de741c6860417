"""A 2-D occupancy grid with an optional height map, and the grid geometry the footstep planner
builds on: the exact clearance of every cell (``clearance_m``, a Euclidean distance transform
measured between cell edges), shortest paths through free cells (``GridGraph``, scipy's
Dijkstra on the 8-connected cell graph), a dilation by a distance (``near_occupied``) and the
exact cells a segment crosses (``crossed_cells``). All are array operations or compiled scipy
routines, with no Python loop per cell.

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
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from ..maps import OCCUPIED, CellGeometry, Grid2D
from ..utils.checks import InvalidValueError, check_positive, check_vector

OCTILE_MAX_RATIO = math.cos(math.pi / 8) + (math.sqrt(2.0) - 1.0) * math.sin(math.pi / 8)
"""max over directions of (length of the shortest 8-connected path of side moves r and diagonal
moves sqrt(2) r) / (Euclidean length) = 1.0824, reached at 22.5 degrees."""


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


def clearance_m(blocked: np.ndarray, resolution_m: float) -> np.ndarray:
    """(num_y, num_x) float: the exact distance from the nearest point of each cell to the nearest
    point of a blocked cell, m, with everything off the map blocked too (so 0 for blocked cells
    and their 8 neighbours). Two cells whose indices differ by (di, dj) are
    hypot(max(|di| - 1, 0), max(|dj| - 1, 0)) cells apart, edge to edge, which is the distance
    between the centres of the one cell and the other grown by one cell each way: so this is one
    exact Euclidean distance transform of the blocked cells grown by one cell (scipy)."""
    blocked = np.asarray(blocked, bool)
    padded = np.ones((blocked.shape[0] + 2, blocked.shape[1] + 2), bool)
    padded[1:-1, 1:-1] = blocked
    grown = padded[1:-1, 1:-1].copy()
    for di in (0, 1, 2):  # the 3 x 3 dilation as nine shifted ORs (scipy's is several times slower)
        for dj in (0, 1, 2):
            grown |= padded[di:di + blocked.shape[0], dj:dj + blocked.shape[1]]
    return ndimage.distance_transform_edt(~grown) * float(resolution_m)


class GridGraph:
    """The 8-connected graph of a grid's free cells, built once; shortest paths from seed cells
    by scipy's Dijkstra (compiled: a 160 x 160 map takes milliseconds).

    A side move costs r, a diagonal sqrt(2) r, each times 1 + the mean ``cost_per_m`` of its two
    cells (an inflation cost, in the manner of Nav2's costmap inflation, that keeps paths off
    obstacles; without it the result is a length). With ``corner_cutting`` a diagonal move between
    two free cells is allowed whatever the two cells beside it hold (a relaxation: such paths are
    never longer than a continuous path's cells allow); without it both must be free too."""

    def __init__(self, free: np.ndarray, resolution_m: float, *, cost_per_m: np.ndarray | None = None,
                 corner_cutting: bool = True):
        free = np.asarray(free, bool)
        self.shape = free.shape
        num_y, num_x = free.shape
        self.cells = np.flatnonzero(free)
        """(N,) flat index of each node's cell."""
        ids = np.full((num_y + 2, num_x + 2), -1, np.int64)
        ids[1:-1, 1:-1].flat[self.cells] = np.arange(self.cells.size)
        self._node_of = ids[1:-1, 1:-1].ravel()
        weight_scale = None if cost_per_m is None else 1.0 + np.asarray(cost_per_m, float).ravel()[self.cells]
        # CSR built directly: row k lists node k's neighbours in the 8 directions (both directions
        # of every edge stored, so scipy needs no symmetrising transpose per query), with no COO
        # sort (a planner builds this once per map: it is most of its set-up time)
        ids_flat, stride = ids.ravel(), num_x + 2
        here = (self.cells // num_x + 1) * stride + self.cells % num_x + 1  # (N,) flat index into ids
        neighbours, weights = [], []
        for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1), (0, -1), (-1, 0), (-1, -1), (-1, 1)):
            b = ids_flat[here + (di * stride + dj)]
            if di and dj and not corner_cutting:
                b[(ids_flat[here + di * stride] < 0) | (ids_flat[here + dj] < 0)] = -1
            w = np.full(b.size, resolution_m * (math.sqrt(2.0) if di and dj else 1.0))
            if weight_scale is not None:
                w *= 0.5 * (weight_scale + weight_scale[b])  # b = -1 picks a value that is dropped below
            neighbours.append(b)
            weights.append(w)
        neighbours, weights = np.stack(neighbours, axis=1), np.stack(weights, axis=1)  # (N, 8)
        has = neighbours >= 0
        n = self.cells.size
        indptr = np.concatenate([[0], np.cumsum(has.sum(axis=1))])
        self.matrix = csr_matrix((weights[has], neighbours[has].astype(np.int32), indptr.astype(np.int32)), shape=(n, n))

    def distances(self, seeds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """From every cell to the nearest of the ``seeds`` (num_y, num_x) bool cells that are free:
        (distance (num_y, num_x) float, m or cost, inf where no path; next (num_y, num_x) int64, the
        flat index of the next cell on a shortest path towards the seeds, -1 at seeds and where
        there is no path)."""
        seed_nodes = self._node_of[np.flatnonzero(np.asarray(seeds, bool).ravel())]
        seed_nodes = seed_nodes[seed_nodes >= 0]
        dist = np.full(self.shape, np.inf)
        nxt = np.full(self.shape, -1, np.int64)
        if seed_nodes.size == 0 or self.cells.size == 0:
            return dist, nxt
        d, pred, _ = dijkstra(self.matrix, directed=True, indices=seed_nodes, min_only=True,
                              return_predecessors=True)
        dist.flat[self.cells] = d
        has = pred >= 0
        nxt.flat[self.cells[has]] = self.cells[pred[has]]
        return dist, nxt


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


def terrain_grid_map(terrain, center_xy_m, size_m: float = 8.0) -> GridMap:
    """A free ``size_m`` square map around ``center_xy_m`` with the heights of a terrain (a
    ``scenes.terrain.TerrainGrid``: ``spacing_m``, ``origin_xy_m``, ``height_at``), for the footstep
    planner. Its cells are the terrain's sample cells (same spacing, corners on the samples) and each
    reads the height at its centre: a riser's cell, the one the hfield ramps over, reads halfway
    between its treads (5 cm off both at 0.10 m risers, more than the planner's 2 cm foothold
    spread), so no planned sole reaches onto a ramp (with cells at any offset to the samples, 33 of
    152 planned soles on 8 plans did)."""
    res = float(terrain.spacing_m)
    n = int(round(size_m / res))
    corner = np.asarray(center_xy_m, float) - size_m / 2
    origin = terrain.origin_xy_m + np.round((corner - terrain.origin_xy_m) / res) * res
    centers = origin[:, None] + (np.arange(n) + 0.5) * res  # (2, n): x, y of cell centres
    heights = terrain.height_at(centers[0][None, :], centers[1][:, None])  # (num_y, num_x)
    return GridMap.from_array(np.zeros((n, n), bool), origin_xy_m=tuple(origin), resolution_m=res, height_m=heights)
