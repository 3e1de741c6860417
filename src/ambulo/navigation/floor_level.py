"""Levelling a camera pose estimate on the floor it sees, before its depth is fused.

The robot walks on a flat floor at z = 0 (``NavWorld``'s convention; the VO's map frame is the
world's, set at the first frame). A small pitch or roll error of the estimated camera pose raises the
far floor by ``range * error``: 0.5 deg at 4 m is 3.5 cm, enough to put it into the occupancy band
(whose first voxel centre is 5 cm up: a surface above 2.5 cm marks the cell). In randomized full-mode
episodes the VO's pitch drifted 0.2-0.5 deg within 15 s (apartment 60; mapping mode, with the true
pose and the same depth noise, stays clean), the far floor of whole rooms read occupied, and the
route planner found no route for the rest of the episode (11 of the 18 randomized stuck episodes
ended in 30-116 "no route" replans).

``level_on_floor`` fits the floor plane among the frame's depth points that the estimate puts near
z = 0 (RANSAC, then least squares on its inliers, so wall bottoms and low clutter drop out) and,
when the fit is trustworthy (enough points, spread over enough depth and across, a tilt and a
height offset within plausible estimate errors), returns the pose rotated about the camera centre by the smallest
rotation that levels that plane and moved vertically to put it at z = 0. Position in x, y and
the yaw are left as estimated (the rotation's axis is horizontal). Only the map sees the levelled
pose; the localizer's estimate is not changed.

Its own error, on true camera poses along scripted walks through apartments 200 and 201 with the
randomized depth noise (1 % of range): tilt median 0.36 deg, p90 0.66 deg; height p90 1.9 cm
(0.19 / 0.45 deg without the noise): below the VO's drift it corrects in randomized episodes, not
far below it, so it is for a VO that drifts, not for a true pose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..utils.validate import Checked


@dataclass(kw_only=True)
class FloorLevelCfg(Checked):
    near_floor_m: float = 0.15
    """Points the estimate puts within this of z = 0 are floor candidates, m (a 1 deg error at 4 m
    is 7 cm)."""
    inlier_m: float = 0.025
    """The refit keeps the candidates within this of the first plane, m (the floor, not the shoes
    and books on it)."""
    depth_range_m: tuple[float, float] = (0.5, 4.0)
    """Depths used, m (the mapper fuses up to 4 m)."""
    stride_px: int = 4
    """Every this many pixels in each direction."""
    min_points: int = 200
    ransac_trials: int = 60
    """Planes tried through three candidate points each."""
    min_depth_spread_m: float = 0.8
    """The inliers' depths must span this much (a plane from a patch does not fix the pitch), m."""
    min_extent_m: float = 0.12
    """The inliers' spread (std) across the plane's narrower direction must be at least this: a strip
    of floor along a wall pins the pitch along it but not the roll across it, m. 0.3 refused most
    frames in a 1 m wide passage (randomized apartment 24: the VO's camera 5 cm high and 0.4-0.8 deg
    off there, the floor around the goal read occupied, no route)."""
    max_tilt_rad: float = 0.05
    """A fitted floor tilted more than this (3 deg) is not the floor's error but something else
    (a ramp, a low table top): no correction, rad."""
    max_height_m: float = 0.08
    """Likewise a floor offset more than this from z = 0 under the camera, m."""


@dataclass
class FloorFit:
    """A levelling correction (``level_on_floor``)."""

    pose_wc: np.ndarray
    """(4, 4) the levelled camera-to-world pose."""
    tilt_rad: float
    """Angle between the fitted floor's normal and the vertical (what was corrected)."""
    height_offset_m: float
    """Camera height over the fitted floor minus its estimated height, m."""
    num_points: int


def level_on_floor(depth_m: np.ndarray, intrinsics: np.ndarray, pose_wc: np.ndarray,
                   cfg: FloorLevelCfg | None = None) -> FloorFit | None:
    """The pose levelled on the floor seen in ``depth_m`` (module docstring), or None when the
    frame does not show enough floor to trust the fit."""
    c = cfg or FloorLevelCfg()
    depth = np.asarray(depth_m, np.float32)[::c.stride_px, ::c.stride_px]
    k = np.asarray(intrinsics, float)
    v, u = np.mgrid[0:depth.shape[0], 0:depth.shape[1]]
    u, v = u * c.stride_px, v * c.stride_px
    lo, hi = c.depth_range_m
    ok = np.isfinite(depth) & (depth >= lo) & (depth <= hi)
    if ok.sum() < c.min_points:
        return None
    z = depth[ok].astype(float)
    p_c = np.stack([(u[ok] - k[0, 2]) / k[0, 0] * z, (v[ok] - k[1, 2]) / k[1, 1] * z, z], -1)
    pose = np.asarray(pose_wc, float)
    p_w = p_c @ pose[:3, :3].T + pose[:3, 3]
    near = np.flatnonzero(np.abs(p_w[:, 2]) < c.near_floor_m)
    if len(near) < c.min_points:
        return None
    # RANSAC: the plane through three candidates that the most candidates lie within ``inlier_m``
    # of (the floor, not the bottoms of walls and furniture or the clutter on it), then a least-
    # squares refit on its inliers
    rng = np.random.default_rng(len(near))
    pts = p_w[near]
    best, best_count = None, 0
    for trio in rng.integers(0, len(pts), size=(c.ransac_trials, 3)):
        a, b, d3 = pts[trio]
        n = np.cross(b - a, d3 - a)
        norm = np.linalg.norm(n)
        if norm < 1e-9 or abs(n[2]) < norm * math.cos(c.max_tilt_rad * 2):
            continue  # degenerate, or far from level: not the floor's estimate error
        n = n / norm
        count = int((np.abs((pts - a) @ n) < c.inlier_m).sum())
        if count > best_count:
            best, best_count = (n, a), count
    if best is None or best_count < c.min_points:
        return None
    sel_local = np.abs((pts - best[1]) @ best[0]) < c.inlier_m
    fit, extent = _plane(pts[sel_local])
    if extent < c.min_extent_m:
        return None
    sel = np.zeros(len(p_w), bool)
    sel[near[sel_local]] = True
    if np.ptp(z[sel]) < c.min_depth_spread_m:
        return None
    n, d = fit[:3], fit[3]
    tilt = math.acos(min(1.0, float(n[2])))
    centre = pose[:3, 3]
    height = float(n @ centre + d)  # the camera's distance above the fitted floor
    offset = height - float(centre[2])
    if tilt > c.max_tilt_rad or abs(offset) > c.max_height_m:
        return None
    rot = _rotation_onto_z(n)
    out = pose.copy()
    out[:3, :3] = rot @ pose[:3, :3]
    out[2, 3] = height
    return FloorFit(out, tilt, offset, int(sel.sum()))


def _plane(points: np.ndarray) -> tuple[np.ndarray, float]:
    """((4,) n_x, n_y, n_z, d of the least-squares plane n . p + d = 0 through ``points`` (K, 3),
    |n| = 1 and n_z > 0; the points' spread (std) along the plane's narrower direction, m)."""
    mean = points.mean(0)
    _, sv, vt = np.linalg.svd(points - mean, full_matrices=False)
    n = vt[-1]
    n = n if n[2] >= 0 else -n
    return np.concatenate([n, [-float(n @ mean)]]), float(sv[1] / math.sqrt(len(points)))


def _rotation_onto_z(n: np.ndarray) -> np.ndarray:
    """(3, 3) the smallest rotation taking the unit vector ``n`` onto +z (Rodrigues; its axis is
    horizontal, so headings are kept)."""
    axis = np.cross(n, [0.0, 0.0, 1.0])
    s, cos = float(np.linalg.norm(axis)), float(n[2])
    if s < 1e-12:
        return np.eye(3)
    a = axis / s
    kx = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + s * kx + (1 - cos) * kx @ kx


__all__ = ["FloorFit", "FloorLevelCfg", "level_on_floor"]
