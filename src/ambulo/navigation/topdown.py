"""The top-down picture of a navigation episode, drawn with NumPy (no per-pixel Python loops): the
map as the robot knows it, the route, the footstep plan, the walked and estimated paths, the goal
and the robot.

Colours (``COLORS``): unknown grey, free white, occupied black, free cells within the body radius
of an obstacle (the inflation the planners keep clear of) tinted blue; route orange, left feet
green, right feet red, estimated path magenta, true path blue, goal gold, robot teal.

Pixels: the picture is y up. A world point (x, y) lies at column ``(x - ox) * s`` and row
``H - (y - oy) * s`` (``TopDown.pixel_of``), ``s`` being pixels per metre and (ox, oy) the map's
lower-left corner; cell (iy, ix) covers the pixels whose centres fall in it.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from ..maps import OCCUPIED, UNKNOWN, Grid2D
from ..robots import humanoid

COLORS = {
    "unknown": (150, 150, 160), "free": (255, 255, 255), "occupied": (0, 0, 0), "inflated": (200, 212, 245),
    "route": (255, 150, 0), "left": (40, 170, 60), "right": (220, 40, 40), "estimated": (200, 0, 200),
    "true": (30, 90, 230), "goal": (230, 180, 0), "robot": (0, 140, 150), "heading": (255, 255, 255),
}
"""RGB uint8 colour of each layer."""

FOOT_SIZE_M = (0.22, 0.10)
"""Sole rectangle drawn per footstep (length, width), m: the footstep planner's default sole."""


def map_rgb(grid: Grid2D, inflation_radius_m: float = humanoid.BODY_RADIUS_M) -> np.ndarray:
    """(num_y, num_x, 3) uint8 picture of ``grid``, one pixel per cell, row 0 = lowest y: unknown
    grey, free white, occupied black, free cells within ``inflation_radius_m`` of an occupied
    cell's centre tinted (``COLORS``)."""
    occ = grid.occupancy
    occupied, unknown = occ >= OCCUPIED, occ == UNKNOWN
    rgb = np.empty((*occ.shape, 3), np.uint8)
    rgb[:] = COLORS["free"]
    if occupied.any():
        dist_m = ndimage.distance_transform_edt(~occupied) * grid.resolution_m
        rgb[(dist_m <= inflation_radius_m) & ~occupied] = COLORS["inflated"]
    rgb[unknown] = COLORS["unknown"]
    rgb[occupied] = COLORS["occupied"]
    return rgb


def crop(grid: Grid2D, box_xy_m) -> Grid2D:
    """The cells of ``grid`` covering ``box_xy_m`` (x0, y0, x1, y1), m, on the same lattice (the
    box grows to whole cells); cells outside ``grid`` are unknown."""
    x0, y0, x1, y1 = (float(v) for v in box_xy_m)
    (ox, oy), r = grid.origin_xy_m, grid.resolution_m
    ny, nx = grid.shape
    ix0, iy0 = math.floor((x0 - ox) / r + 1e-9), math.floor((y0 - oy) / r + 1e-9)
    ix1, iy1 = max(ix0 + 1, math.ceil((x1 - ox) / r - 1e-9)), max(iy0 + 1, math.ceil((y1 - oy) / r - 1e-9))
    occ = np.full((iy1 - iy0, ix1 - ix0), UNKNOWN, np.int8)
    sy0, sy1, sx0, sx1 = max(iy0, 0), min(iy1, ny), max(ix0, 0), min(ix1, nx)
    if sy0 < sy1 and sx0 < sx1:
        occ[sy0 - iy0:sy1 - iy0, sx0 - ix0:sx1 - ix0] = grid.occupancy[sy0:sy1, sx0:sx1]
    return Grid2D(occupancy=occ, origin_xy_m=(ox + ix0 * r, oy + iy0 * r), resolution_m=r)


def stamp(img: np.ndarray, rc: np.ndarray, radius_px: float, color) -> None:
    """Paint discs of ``radius_px`` at the continuous pixel positions ``rc`` (K, 2) (row, column)
    into ``img`` (H, W, 3) in place; parts outside the picture are dropped."""
    rc = np.asarray(rc, np.float64).reshape(-1, 2)
    if rc.size == 0:
        return
    r = max(0, math.ceil(radius_px - 0.5))
    d = np.arange(-r, r + 1)
    dy, dx = np.meshgrid(d, d, indexing="ij")
    keep = dy ** 2 + dx ** 2 <= max(radius_px, 0.5) ** 2
    offsets = np.stack([dy[keep], dx[keep]], -1)
    px = (np.floor(rc)[:, None, :] + offsets[None]).reshape(-1, 2).astype(np.int64)
    h, w = img.shape[:2]
    ok = (px[:, 0] >= 0) & (px[:, 0] < h) & (px[:, 1] >= 0) & (px[:, 1] < w)
    img[px[ok, 0], px[ok, 1]] = color


def polyline_points(rc: np.ndarray, spacing_px: float = 0.5) -> np.ndarray:
    """Points every ``spacing_px`` along the polyline ``rc`` (K, 2), vertices included: (M, 2)."""
    rc = np.asarray(rc, np.float64).reshape(-1, 2)
    if len(rc) < 2:
        return rc
    seg = np.diff(rc, axis=0)
    n = np.maximum(1, np.ceil(np.linalg.norm(seg, axis=1) / spacing_px).astype(np.int64))
    which = np.repeat(np.arange(len(seg)), n)
    frac = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n, n)
    return np.concatenate([rc[which] + frac[:, None] * seg[which], rc[-1:]])


def rect_points(centers_rc: np.ndarray, yaws_rad: np.ndarray, half_px: tuple[float, float],
                border_px: float = 1.5, spacing_px: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Sample points of oriented rectangles in pixel space, split into (border, interior) (M, 2)
    each. ``centers_rc`` (F, 2) row/column, ``yaws_rad`` (F,) world yaw (counter-clockwise with y
    up, so clockwise on the picture's rows), ``half_px`` (along the foot, across it)."""
    centers_rc = np.asarray(centers_rc, np.float64).reshape(-1, 2)
    if len(centers_rc) == 0:
        return np.zeros((0, 2)), np.zeros((0, 2))
    hu, hv = half_px
    u = np.linspace(-hu, hu, max(2, math.ceil(2 * hu / spacing_px) + 1))
    v = np.linspace(-hv, hv, max(2, math.ceil(2 * hv / spacing_px) + 1))
    uu, vv = (a.ravel() for a in np.meshgrid(u, v, indexing="ij"))
    border = (np.abs(uu) > hu - border_px) | (np.abs(vv) > hv - border_px)
    c, s = np.cos(yaws_rad)[:, None], np.sin(yaws_rad)[:, None]
    # world offset (u c - v s, u s + v c); rows grow downward, so a world +y is a row decrease
    rows = centers_rc[:, :1] - (uu * s + vv * c)
    cols = centers_rc[:, 1:] + (uu * c - vv * s)
    pts = np.stack([rows, cols], -1)  # (F, P, 2)
    return pts[:, border].reshape(-1, 2), pts[:, ~border].reshape(-1, 2)


def _lighter(color, amount: float = 0.55) -> tuple[int, int, int]:
    return tuple(int(round(c + (255 - c) * amount)) for c in color)


class TopDown:
    """Draws episode layers over one map at ``px_per_m`` pixels per metre (module docstring),
    showing only ``view_xy_m`` (x0, y0, x1, y1), m, when given (an online map covers far more than
    the scene). The map picture is rebuilt only when the grid object changes (mappers make a new
    one per update)."""

    def __init__(self, px_per_m: float, view_xy_m=None):
        self.px_per_m = float(px_per_m)
        self.view_xy_m = None if view_xy_m is None else tuple(float(v) for v in view_xy_m)
        self._grid: Grid2D | None = None
        self._view: Grid2D | None = None
        self._base: np.ndarray | None = None

    def view(self, grid: Grid2D) -> Grid2D:
        """The part of ``grid`` drawn (``grid`` itself without ``view_xy_m``)."""
        self.base(grid)
        return self._view

    def base(self, grid: Grid2D) -> np.ndarray:
        """(H, W, 3) uint8 map picture of ``grid`` at ``px_per_m``, y up (cached per grid object)."""
        if grid is not self._grid:
            view = grid if self.view_xy_m is None else crop(grid, self.view_xy_m)
            rgb = map_rgb(view)
            ny, nx = view.shape
            cell_px = view.resolution_m * self.px_per_m
            h, w = max(1, round(ny * cell_px)), max(1, round(nx * cell_px))
            iy = np.minimum(ny - 1, ((h - 1 - np.arange(h) + 0.5) / cell_px).astype(np.int64))
            ix = np.minimum(nx - 1, ((np.arange(w) + 0.5) / cell_px).astype(np.int64))
            self._base = rgb.take(iy, axis=0).take(ix, axis=1)
            self._grid, self._view = grid, view
        return self._base

    def pixel_of(self, grid: Grid2D, xy_m) -> np.ndarray:
        """(K, 2) float (row, column) of world points (K, 2) on ``grid``'s picture."""
        xy = np.asarray(xy_m, np.float64).reshape(-1, 2)
        h = self.base(grid).shape[0]
        ox, oy = self._view.origin_xy_m
        return np.stack([h - (xy[:, 1] - oy) * self.px_per_m, (xy[:, 0] - ox) * self.px_per_m], -1)

    def draw(self, grid: Grid2D, *, route_xy_m=None, footsteps=None, estimated_xy_m=None, true_xy_m=None,
             goal_xy_m=None, robot_xyyaw=None, goal_tolerance_m: float = 0.3) -> np.ndarray:
        """A new (H, W, 3) uint8 picture: the map, then route, footsteps (a ``nav.FootstepPlan``),
        estimated path, true path, goal and robot, in that order (later layers on top)."""
        img = self.base(grid).copy()
        s = self.px_per_m
        line_px = max(1.0, s * 0.02)
        if route_xy_m is not None and len(route_xy_m):
            stamp(img, polyline_points(self.pixel_of(grid, route_xy_m)), line_px, COLORS["route"])
        if footsteps is not None and len(footsteps.footsteps_xyyaw_w):
            feet = np.asarray(footsteps.footsteps_xyyaw_w, np.float64)
            half = (FOOT_SIZE_M[0] / 2 * s, FOOT_SIZE_M[1] / 2 * s)
            for side, name in ((1, "left"), (-1, "right")):
                mine = np.asarray(footsteps.foot_sides) == side
                border, inside = rect_points(self.pixel_of(grid, feet[mine, :2]), feet[mine, 2], half)
                stamp(img, inside, 0.5, _lighter(COLORS[name]))
                stamp(img, border, 0.5, COLORS[name])
        if estimated_xy_m is not None and len(estimated_xy_m):
            stamp(img, polyline_points(self.pixel_of(grid, estimated_xy_m)), line_px, COLORS["estimated"])
        if true_xy_m is not None and len(true_xy_m):
            stamp(img, polyline_points(self.pixel_of(grid, true_xy_m)), 1.5 * line_px, COLORS["true"])
        if goal_xy_m is not None:
            ring = np.linspace(0, 2 * math.pi, 73)
            circle = np.asarray(goal_xy_m, float)[None] + goal_tolerance_m * np.stack([np.cos(ring), np.sin(ring)], -1)
            stamp(img, polyline_points(self.pixel_of(grid, circle)), line_px, COLORS["goal"])
            stamp(img, self.pixel_of(grid, goal_xy_m), 0.08 * s, COLORS["goal"])
        if robot_xyyaw is not None:
            x, y, yaw = (float(v) for v in robot_xyyaw)
            radius_m = 0.6 * humanoid.BODY_RADIUS_M  # smaller than the body, so the paths stay visible
            stamp(img, self.pixel_of(grid, (x, y)), radius_m * s, COLORS["robot"])
            tip = (x + radius_m * math.cos(yaw), y + radius_m * math.sin(yaw))
            stamp(img, polyline_points(self.pixel_of(grid, [(x, y), tip])), line_px, COLORS["heading"])
        return img


__all__ = ["COLORS", "FOOT_SIZE_M", "TopDown", "crop", "map_rgb", "polyline_points", "rect_points", "stamp"]
