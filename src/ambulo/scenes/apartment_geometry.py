"""Exact 2-D geometry of the apartment's footprints: rotated rectangles and discs.

Everything the apartment knows about "where a solid is" seen from above goes through here, so the
occupancy grid, the clearance of a point, the clearance of a straight segment and the furniture
placement all agree to rounding:

- ``Footprints``: (K,) rectangles (centre, half extents, yaw) and (J,) discs (centre, radius);
- ``rasterize``: a cell is occupied iff its square, shrunk by ``CELL_SHRINK_M`` (so a footprint
  that only touches a cell's border does not occupy it), meets a footprint; rectangles by the
  separating-axis test (the square's two axes and the rectangle's two), discs by the distance
  from the disc's centre to the square;
- ``point_clearance_m`` / ``segment_clearance_m``: the exact Euclidean distance from points /
  straight segments to the nearest footprint (0 inside or across one).

numpy only, vectorized over points or segments (a loop over the few dozen footprints at most).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CELL_SHRINK_M = 1e-6
"""A cell's square is shrunk by this on each side before the intersection test: occupancy is the
open square's, so a wall face lying exactly on a cell border occupies one cell, not two."""


@dataclass(frozen=True)
class Footprints:
    """Obstacle footprints in the world x-y plane, m and rad."""

    rect_center_xy_m: np.ndarray
    """(K, 2) float64 rectangle centres."""
    rect_half_xy_m: np.ndarray
    """(K, 2) float64 half extents along the rectangle's own x and y."""
    rect_yaw_rad: np.ndarray
    """(K,) float64 rotation of the rectangle's x axis from the world x axis."""
    disc_center_xy_m: np.ndarray
    """(J, 2) float64 disc centres."""
    disc_radius_m: np.ndarray
    """(J,) float64 disc radii."""

    @classmethod
    def empty(cls) -> Footprints:
        return cls(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros((0, 2)), np.zeros(0))

    def __len__(self) -> int:
        return len(self.rect_yaw_rad) + len(self.disc_radius_m)


def rect_corners_xy_m(center_xy_m, half_xy_m, yaw_rad) -> np.ndarray:
    """(..., 4, 2) world corners (counter-clockwise) of rectangles (..., 2), (..., 2), (...)."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    axes_x = np.stack([c, s], -1)[..., None, :]
    axes_y = np.stack([-s, c], -1)[..., None, :]
    signs = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], np.float64)
    half = np.asarray(half_xy_m, np.float64)[..., None, :]
    return (np.asarray(center_xy_m, np.float64)[..., None, :]
            + signs[:, :1] * half[..., :1] * axes_x + signs[:, 1:] * half[..., 1:] * axes_y)


def rasterize(fp: Footprints, origin_xy_m, resolution_m: float, shape: tuple[int, int]) -> np.ndarray:
    """(num_y, num_x) bool: cell [iy, ix] (``maps.Grid2D``'s convention: origin = lower-left corner
    of cell [0, 0]) is occupied iff its square shrunk by ``CELL_SHRINK_M`` meets a footprint."""
    ox, oy = float(origin_xy_m[0]), float(origin_xy_m[1])
    r, (ny, nx) = float(resolution_m), shape
    occ = np.zeros((ny, nx), bool)
    half_cell = r / 2 - CELL_SHRINK_M
    corners = rect_corners_xy_m(fp.rect_center_xy_m, fp.rect_half_xy_m, fp.rect_yaw_rad)  # (K, 4, 2)
    for k in range(len(fp.rect_yaw_rad)):
        window = _window(corners[k].min(0), corners[k].max(0), ox, oy, r, ny, nx)
        if window is None:
            continue
        (y0, y1, x0, x1), cx, cy = window
        # separating axes: world x and y are the window bounds (a square outside the rectangle's
        # bounding box is never in the window, up to the shrink checked here); then the
        # rectangle's own axes, where the square's projection has half-width h (|c| + |s|)
        lo, hi = corners[k].min(0), corners[k].max(0)
        sep = ((cx[None, :] + half_cell <= lo[0]) | (cx[None, :] - half_cell >= hi[0])
               | (cy[:, None] + half_cell <= lo[1]) | (cy[:, None] - half_cell >= hi[1]))
        c, s = np.cos(fp.rect_yaw_rad[k]), np.sin(fp.rect_yaw_rad[k])
        dx, dy = cx[None, :] - fp.rect_center_xy_m[k, 0], cy[:, None] - fp.rect_center_xy_m[k, 1]
        spread = half_cell * (abs(c) + abs(s))
        along_x, along_y = dx * c + dy * s, -dx * s + dy * c
        sep |= np.abs(along_x) >= fp.rect_half_xy_m[k, 0] + spread
        sep |= np.abs(along_y) >= fp.rect_half_xy_m[k, 1] + spread
        occ[y0:y1, x0:x1] |= ~sep
    for j in range(len(fp.disc_radius_m)):
        ctr, rad = fp.disc_center_xy_m[j], fp.disc_radius_m[j]
        window = _window(ctr - rad, ctr + rad, ox, oy, r, ny, nx)
        if window is None:
            continue
        (y0, y1, x0, x1), cx, cy = window
        gx = np.maximum(np.abs(cx - ctr[0]) - half_cell, 0.0)[None, :]
        gy = np.maximum(np.abs(cy - ctr[1]) - half_cell, 0.0)[:, None]
        occ[y0:y1, x0:x1] |= gx * gx + gy * gy < rad * rad
    return occ


def _window(lo, hi, ox, oy, r, ny, nx):
    """The cell index window (y0, y1, x0, x1) covering the box [lo, hi] (one cell of slack), and
    the cell centres' x (x1 - x0,) and y (y1 - y0,); None if it misses the grid."""
    x0, y0 = max(int(np.floor((lo[0] - ox) / r)) - 1, 0), max(int(np.floor((lo[1] - oy) / r)) - 1, 0)
    x1, y1 = min(int(np.floor((hi[0] - ox) / r)) + 2, nx), min(int(np.floor((hi[1] - oy) / r)) + 2, ny)
    if x0 >= x1 or y0 >= y1:
        return None
    return (y0, y1, x0, x1), ox + (np.arange(x0, x1) + 0.5) * r, oy + (np.arange(y0, y1) + 0.5) * r


def _to_rect_frame(fp: Footprints, xy: np.ndarray) -> np.ndarray:
    """(K, ..., 2): points ``xy`` (..., 2) in each rectangle's frame."""
    c, s = np.cos(fp.rect_yaw_rad), np.sin(fp.rect_yaw_rad)
    shape = (len(c),) + (1,) * (xy.ndim - 1)
    d = xy[None] - fp.rect_center_xy_m.reshape(shape + (2,))
    c, s = c.reshape(shape), s.reshape(shape)
    return np.stack([d[..., 0] * c + d[..., 1] * s, -d[..., 0] * s + d[..., 1] * c], -1)


def point_clearance_m(fp: Footprints, xy_m: np.ndarray) -> np.ndarray:
    """(...) float64: exact distance from points ``xy_m`` (..., 2) to the nearest footprint, m
    (0 inside one; inf with no footprints)."""
    xy = np.asarray(xy_m, np.float64)
    out = np.full(xy.shape[:-1], np.inf)
    for k in range(len(fp.rect_yaw_rad)):  # one rectangle at a time: memory stays (...)
        local = _to_rect_frame(_one_rect(fp, k), xy)[0]
        gap = np.maximum(np.abs(local) - fp.rect_half_xy_m[k], 0.0)
        np.minimum(out, np.hypot(gap[..., 0], gap[..., 1]), out=out)
    for j in range(len(fp.disc_radius_m)):
        d = np.hypot(xy[..., 0] - fp.disc_center_xy_m[j, 0], xy[..., 1] - fp.disc_center_xy_m[j, 1])
        np.minimum(out, np.maximum(d - fp.disc_radius_m[j], 0.0), out=out)
    return out


def _one_rect(fp: Footprints, k: int) -> Footprints:
    return Footprints(fp.rect_center_xy_m[k:k + 1], fp.rect_half_xy_m[k:k + 1], fp.rect_yaw_rad[k:k + 1],
                      fp.disc_center_xy_m[:0], fp.disc_radius_m[:0])


def point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(...) distance from points p to segments [a, b] (all (..., 2), broadcast)."""
    ab = b - a
    denom = np.maximum((ab * ab).sum(-1), 1e-300)
    t = np.clip(((p - a) * ab).sum(-1) / denom, 0.0, 1.0)
    closest = a + t[..., None] * ab
    return np.hypot(p[..., 0] - closest[..., 0], p[..., 1] - closest[..., 1])


def _segment_hits_box(a: np.ndarray, b: np.ndarray, half: np.ndarray) -> np.ndarray:
    """(...) bool: segment [a, b] (..., 2) meets the closed axis-aligned box |x| <= half (2,)
    (Liang-Barsky clipping)."""
    d = b - a
    t0, t1 = np.zeros(a.shape[:-1]), np.ones(a.shape[:-1])
    ok = np.ones(a.shape[:-1], bool)
    for axis in range(2):
        da, pa = d[..., axis], a[..., axis]
        flat = np.abs(da) < 1e-15
        ok &= ~flat | (np.abs(pa) <= half[axis])
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (-half[axis] - pa) / da, (half[axis] - pa) / da
        lo, hi = np.where(flat, -np.inf, np.minimum(ta, tb)), np.where(flat, np.inf, np.maximum(ta, tb))
        t0, t1 = np.maximum(t0, lo), np.minimum(t1, hi)
    return ok & (t0 <= t1)


def segment_clearance_m(fp: Footprints, a_xy_m: np.ndarray, b_xy_m: np.ndarray) -> np.ndarray:
    """(...) float64: exact distance from straight segments [a, b] (each (..., 2)) to the nearest
    footprint, m: 0 if a segment meets one; else, for a rectangle, the least of its end points'
    distances to the rectangle and the rectangle's corners' distances to the segment (the
    closest pair of two disjoint convex polygons has a vertex of one of them)."""
    a, b = np.broadcast_arrays(np.asarray(a_xy_m, np.float64), np.asarray(b_xy_m, np.float64))
    out = np.full(a.shape[:-1], np.inf)
    signs = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], np.float64)
    for k in range(len(fp.rect_yaw_rad)):
        one, half = _one_rect(fp, k), fp.rect_half_xy_m[k]
        la, lb = _to_rect_frame(one, a)[0], _to_rect_frame(one, b)[0]
        ga, gb = np.maximum(np.abs(la) - half, 0.0), np.maximum(np.abs(lb) - half, 0.0)
        d = np.minimum(np.hypot(ga[..., 0], ga[..., 1]), np.hypot(gb[..., 0], gb[..., 1]))
        for corner in signs * half:
            d = np.minimum(d, point_segment_distance(corner, la, lb))
        d = np.where(_segment_hits_box(la, lb, half), 0.0, d)
        np.minimum(out, d, out=out)
    for j in range(len(fp.disc_radius_m)):
        d = point_segment_distance(fp.disc_center_xy_m[j], a, b) - fp.disc_radius_m[j]
        np.minimum(out, np.maximum(d, 0.0), out=out)
    return out


def rect_distances_m(center_xy_m, half_xy_m, yaw_rad, centers_xy_m, halves_xy_m, yaws_rad) -> np.ndarray:
    """(K,) exact distances from one rotated rectangle to K others, m (0 where they overlap): the
    separating-axis test for overlap (each rectangle's two axes), else the least vertex-to-edge
    distance either way (the closest pair of two disjoint convex polygons has a vertex)."""
    a = rect_corners_xy_m(np.asarray(center_xy_m, float), np.asarray(half_xy_m, float), float(yaw_rad))  # (4, 2)
    b = rect_corners_xy_m(np.asarray(centers_xy_m, float).reshape(-1, 2), np.asarray(halves_xy_m, float).reshape(-1, 2),
                          np.asarray(yaws_rad, float).reshape(-1))  # (K, 4, 2)
    a = np.broadcast_to(a, b.shape)
    separated = np.zeros(len(b), bool)
    for poly in (a, b):  # the axes of each: its edge directions
        for edge in (0, 1):
            axis = poly[:, edge + 1] - poly[:, edge]  # (K, 2)
            pa, pb = (a * axis[:, None]).sum(-1), (b * axis[:, None]).sum(-1)  # (K, 4)
            separated |= (pa.max(1) <= pb.min(1)) | (pb.max(1) <= pa.min(1))
    a_start, a_end = a, np.roll(a, -1, axis=1)
    b_start, b_end = b, np.roll(b, -1, axis=1)
    vertex_a = point_segment_distance(a[:, :, None], b_start[:, None], b_end[:, None])  # (K, 4, 4)
    vertex_b = point_segment_distance(b[:, :, None], a_start[:, None], a_end[:, None])
    dist = np.minimum(vertex_a.min((1, 2)), vertex_b.min((1, 2)))
    return np.where(separated, dist, 0.0)


__all__ = ["CELL_SHRINK_M", "Footprints", "point_clearance_m", "point_segment_distance", "rasterize", "rect_corners_xy_m",
           "rect_distances_m", "segment_clearance_m"]
