"""The map as the footstep planner tests steps against it: built once per (map, config).

A step moves the swing foot from its previous footstep past the stance foot to a new footstep.
It passes when, all against the occupancy grid (whose occupied cells cover the obstacles):
  * sole: samples of the new sole at most one cell apart (every sole point is within 0.71 cell
    of one) lie in no cell within one cell of an occupied cell, so the sole keeps >= 0.29 cell;
  * legs: samples at most ``SEGMENT_SPACING_CELLS`` apart on the segment stance foot -> new foot
    (nothing between the legs) and on the swing segment previous -> new footstep (the foot passes
    over nothing) pass the same test, so both segments keep >= 0.25 cell;
  * body: every cell that the feet's midpoint crosses, moving from (previous + stance) / 2 to
    (new + stance) / 2, is a body cell: a cell every point of which keeps ``body_clearance_m``
    from every occupied cell, measured exactly between cell edges (``grid_map.clearance_m``).
    Each point of that track thus keeps ``body_clearance_m``; the cells are found exactly
    (``crossed_cells``), and the heuristic's distance field runs over the same body cells. A
    0.60 m door between grid-aligned walls leaves the midpoint a channel of two cells (0.10 m)
    for a 0.25 m clearance, as the continuous geometry does;
  * terrain (with a height map): the heights under the sole samples differ by at most
    ``max_foothold_spread_m``; the foot stands on the highest, and the caller limits the rise.
Off the map counts as occupied.
"""

from __future__ import annotations

import math

import numpy as np

from .footstep_lattice import Lattice, compose
from .grid_map import GridGraph, GridMap, clearance_m, crossed_cells, near_occupied

GUIDE_MARGIN_M = 0.3
"""The body path the planner's walks follow stays this much farther from obstacles than it must,
where it can (``GUIDE_COST_PER_M``)."""
GUIDE_COST_PER_M = 3.0
"""Extra cost per metre of body path at the closest the body may go, falling linearly to 0 at
``GUIDE_MARGIN_M`` farther (an inflation cost in the manner of Nav2's costmap inflation), so the
path keeps to the middle of corridors and doors."""
PAD = 2
"""Border of blocked cells around the padded arrays (off the map = blocked)."""


class FootstepChecks:
    """Padded, flattened map layers and the vectorized step test (module docstring)."""

    def __init__(self, grid: GridMap, cfg, lattice: Lattice):
        self.grid, self.cfg, self.lattice = grid, cfg, lattice
        r = grid.resolution_m
        num_y, num_x = grid.shape
        self.shape_p = (num_y + 2 * PAD, num_x + 2 * PAD)
        """(rows, columns) of the padded layers; cell [iy, ix] of the map is [iy + PAD, ix + PAD]."""
        self.clearance_m = clearance_m(grid.occupied, r)
        """(num_y, num_x) exact distance from each cell to the nearest occupied cell (or the map's
        edge), edge to edge, m."""
        clear_p = np.zeros(self.shape_p)
        clear_p[PAD:-PAD, PAD:-PAD] = self.clearance_m
        self.clearance_flat = clear_p.ravel()
        """Flat padded ``clearance_m`` (0 off the map)."""
        near = np.ones(self.shape_p, bool)
        near[PAD:-PAD, PAD:-PAD] = self.clearance_m <= 0.0
        self.near_occupied = near.ravel()
        """Flat padded bool: occupied or next to an occupied cell (sole and leg samples)."""
        self.body_free = self.clearance_m >= cfg.body_clearance_m - 1e-9
        """(num_y, num_x) bool: the body cells, where the feet's midpoint may go."""
        body_blocked = np.ones(self.shape_p, bool)
        body_blocked[PAD:-PAD, PAD:-PAD] = ~self.body_free
        self.body_blocked = body_blocked.ravel()
        self.body_lines = math.floor(lattice.max_swing_m / 2 / r) + 1
        """Grid lines one body move can cross along an axis (it is at most D_swing / 2 long)."""
        self.guide_free = self.body_free.copy()
        """(num_y, num_x) bool: where the body path may go: body cells, and no closer than the
        feet's reach to a height step too high to take (the heuristic's field ignores heights)."""
        self.height = None
        if grid.height_m is not None:
            height = np.zeros(self.shape_p)
            height[PAD:-PAD, PAD:-PAD] = grid.height_m
            self.height = height.ravel()
            cliff = _height_steps(grid.height_m, min(cfg.max_step_up_m, cfg.max_step_down_m))
            self.guide_free &= ~near_occupied(cliff, r, lattice.max_step_reach_m, from_cell_centers=True)
        guide_blocked = np.ones(self.shape_p, bool)
        guide_blocked[PAD:-PAD, PAD:-PAD] = ~self.guide_free
        self.guide_blocked = guide_blocked.ravel()
        tight = np.clip(1.0 - (self.clearance_m - cfg.body_clearance_m) / GUIDE_MARGIN_M, 0.0, 1.0)
        self.guide_graph = GridGraph(self.guide_free, r, cost_per_m=GUIDE_COST_PER_M * tight, corner_cutting=False)
        """Cell graph of the body path (``GoalHeuristic.path``)."""
        self._body_graph: GridGraph | None = None

    @property
    def body_graph(self) -> GridGraph:
        """Cell graph of the heuristic's geodesic: the body cells, lengths only (built on first use)."""
        if self._body_graph is None:
            self._body_graph = GridGraph(self.body_free, self.grid.resolution_m)
        return self._body_graph

    def cells(self, x_m, y_m) -> np.ndarray:
        """Flat indices into the padded layers of world points (any shape, m); points off the map
        land on the blocked border."""
        (ox, oy), r = self.grid.origin_xy_m, self.grid.resolution_m
        num_y, num_x = self.shape_p
        ix = np.floor((np.asarray(x_m) - ox) / r) + PAD
        iy = np.floor((np.asarray(y_m) - oy) / r) + PAD
        ix = np.minimum(np.maximum(ix, 0), num_x - 1).astype(np.intp)
        iy = np.minimum(np.maximum(iy, 0), num_y - 1).astype(np.intp)
        return iy * num_x + ix

    def cell_center(self, flat_index) -> np.ndarray:
        """(..., 2) world (x, y) of the centres of padded cells given by flat index, m."""
        (ox, oy), r = self.grid.origin_xy_m, self.grid.resolution_m
        iy, ix = np.divmod(np.asarray(flat_index), self.shape_p[1])
        return np.stack([ox + (ix - PAD + 0.5) * r, oy + (iy - PAD + 0.5) * r], axis=-1)

    def steps(self, prev_xy, stance, new) -> tuple[np.ndarray, np.ndarray]:
        """Test K steps: the swing foot moves from ``prev_xy`` ((K, 2) or (2,)) past the stance foot
        ``stance`` ((K, 3) or (3,)) to ``new`` (K, 3); world frame, m and rad. Returns ``free`` (K,)
        bool (sole, legs, body and foothold pass) and the terrain height under each new sole (K,), m.
        The rise from the stance foot is the caller's to check (``rise_ok``)."""
        lat = self.lattice
        sole = lat.sole_points_m
        stance = np.broadcast_to(stance, new.shape)
        prev_xy = np.broadcast_to(prev_xy, (len(new), 2))
        new_x, new_y, stance_x, stance_y = new[:, :1], new[:, 1:2], stance[:, :1], stance[:, 1:2]
        prev_x, prev_y = prev_xy[:, :1], prev_xy[:, 1:2]
        c, s = np.cos(new[:, 2:3]), np.sin(new[:, 2:3])
        tb, tw = lat.between_fractions, lat.swing_fractions
        xs = np.concatenate([new_x + c * sole[:, 0] - s * sole[:, 1], stance_x + (new_x - stance_x) * tb,
                             prev_x + (new_x - prev_x) * tw], axis=1)
        ys = np.concatenate([new_y + s * sole[:, 0] + c * sole[:, 1], stance_y + (new_y - stance_y) * tb,
                             prev_y + (new_y - prev_y) * tw], axis=1)
        cells = self.cells(xs, ys)
        free = ~self.near_occupied[cells].any(axis=1) & self.body_track_free(
            0.5 * np.concatenate([prev_x + stance_x, prev_y + stance_y], axis=1),
            0.5 * np.concatenate([new_x + stance_x, new_y + stance_y], axis=1))
        if self.height is None:
            return free, np.zeros(len(new))
        under_sole = self.height[cells[:, :len(sole)]]
        top = under_sole.max(axis=1)
        return free & (top - under_sole.min(axis=1) <= self.cfg.max_foothold_spread_m), top

    def clearance_at(self, x_m: float, y_m: float) -> float:
        """``clearance_m`` of the cell holding the world point (x, y) (0 off the map), m; scalar
        arithmetic for the walks' step-by-step steering."""
        (ox, oy), r = self.grid.origin_xy_m, self.grid.resolution_m
        num_y, num_x = self.shape_p
        ix = min(max(math.floor((x_m - ox) / r) + PAD, 0), num_x - 1)
        iy = min(max(math.floor((y_m - oy) / r) + PAD, 0), num_y - 1)
        return float(self.clearance_flat[iy * num_x + ix])

    def body_track_free(self, from_xy: np.ndarray, to_xy: np.ndarray) -> np.ndarray:
        """(K,) bool: does every cell that the segments ``from_xy`` -> ``to_xy`` ((K, 2) each, m,
        world; at most D_swing / 2 long) cross lie in the body cells?"""
        (ox, oy), r = self.grid.origin_xy_m, self.grid.resolution_m
        u, v = crossed_cells((from_xy[:, 0] - ox) / r, (from_xy[:, 1] - oy) / r, (to_xy[:, 0] - ox) / r,
                             (to_xy[:, 1] - oy) / r, self.body_lines)
        return ~self.body_blocked[self.cells(ox + u * r, oy + v * r)].any(axis=1)

    def body_segment_free(self, x0_m: float, y0_m: float, x1_m: float, y1_m: float) -> bool:
        """``body_track_free`` for one segment (x0, y0) -> (x1, y1) (m, world; any length) in
        plain Python, for the walks' one-step-at-a-time tests: the same cells, one point inside
        each piece between the segment's crossings with the grid lines, and its end."""
        (ox, oy), r = self.grid.origin_xy_m, self.grid.resolution_m
        u0, v0, u1, v1 = (x0_m - ox) / r, (y0_m - oy) / r, (x1_m - ox) / r, (y1_m - oy) / r
        du, dv = u1 - u0, v1 - v0
        ts = [0.0, 1.0]
        if du != 0.0:
            ts += [(line - u0) / du for line in range(math.floor(min(u0, u1)) + 1, math.floor(max(u0, u1)) + 1)]
        if dv != 0.0:
            ts += [(line - v0) / dv for line in range(math.floor(min(v0, v1)) + 1, math.floor(max(v0, v1)) + 1)]
        ts.sort()
        num_y, num_x = self.shape_p
        blocked = self.body_blocked
        for t in [0.5 * (a + b) for a, b in zip(ts, ts[1:])] + [1.0]:
            ix = min(max(math.floor(u0 + du * t) + PAD, 0), num_x - 1)
            iy = min(max(math.floor(v0 + dv * t) + PAD, 0), num_y - 1)
            if blocked[iy * num_x + ix]:
                return False
        return True

    def rise_ok(self, rise_m) -> np.ndarray:
        """Is a change of foot height (new - stance, m) within the step up/down limits?"""
        return (rise_m <= self.cfg.max_step_up_m) & (-rise_m <= self.cfg.max_step_down_m)

    def stance_blocked(self, feet_xyyaw: np.ndarray) -> bool:
        """Does a sole of the two feet ``feet_xyyaw`` (2, 3) touch an obstacle, or their midpoint
        lie outside the body cells?"""
        sole = self.lattice.sole_points_m
        pts = compose(feet_xyyaw[:, None], np.concatenate([sole, np.zeros((len(sole), 1))], axis=1)[None])
        mid = feet_xyyaw[:, :2].mean(axis=0)
        return bool(self.near_occupied[self.cells(pts[..., 0], pts[..., 1])].any()
                    or self.body_blocked[self.cells(mid[0], mid[1])])

    def sole_height(self, foot_xyyaw) -> float:
        """Terrain height the foot ``foot_xyyaw`` (3,) stands on (0 without a height map), m."""
        if self.height is None:
            return 0.0
        sole = self.lattice.sole_points_m
        pts = compose(foot_xyyaw, np.concatenate([sole, np.zeros((len(sole), 1))], axis=1))
        return float(self.height[self.cells(pts[:, 0], pts[:, 1])].max())


def _height_steps(height_m: np.ndarray, max_step_m: float) -> np.ndarray:
    """(num_y, num_x) bool: cells whose height differs from an 8-neighbour's by more than ``max_step_m``."""
    out = np.zeros(height_m.shape, bool)
    num_y, num_x = height_m.shape
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                here = height_m[max(0, -di):num_y - max(0, di), max(0, -dj):num_x - max(0, dj)]
                there = height_m[max(0, di):num_y - max(0, -di), max(0, dj):num_x - max(0, -dj)]
                out[max(0, -di):num_y - max(0, di), max(0, -dj):num_x - max(0, dj)] |= np.abs(here - there) > max_step_m
    return out
