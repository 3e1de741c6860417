"""Object goals in the world from detections: where a detected object is (depth + camera pose), the
views of one object fused, and where to stand to face it.

A detection is a box (and, from a model with masks, a mask) in a head-camera frame. Its pixels'
depths back-projected through the intrinsics and the camera pose (``RgbdFrame`` conventions: OpenCV
axes, ``pose_wc`` camera-to-world) give points on the object's visible surface; their median (per
axis) is the view's point: robust to the background a box holds and to the mask's edge pixels. A
box without a mask keeps its central part only (``box_core``) for the same reason.

Views are fused per label (``ObjectMap``): a view joins the track whose point is within
``merge_radius_m`` (the track's point is the median of its views), else starts one; a track is
confirmed after ``min_views`` views, so one false detection never sends the robot anywhere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..maps import Grid2D
from ..utils.validate import Checked


@dataclass(kw_only=True)
class LocalizeCfg(Checked):
    box_core: float = 0.5
    """Without a mask, the central fraction of the box (each side) whose pixels count."""
    min_pixels: int = 12
    """A view with fewer valid depth pixels on the object gives no point."""
    max_depth_m: float = 6.0
    """Depths beyond this (or 0 / non-finite: nothing seen) are not used, m."""
    min_height_m: float = 0.05
    """Points below this height are floor seen through the mask's edge, not the object, m."""


def object_pixels(box_px, mask: np.ndarray | None, shape_hw: tuple[int, int], box_core: float) -> np.ndarray:
    """(H, W) bool: the pixels that belong to the detection (its mask inside its box, else the box's core)."""
    h, w = shape_hw
    x0, y0, x1, y1 = (float(v) for v in box_px)
    if mask is not None:
        sel = np.zeros((h, w), bool)
        c0, r0 = max(int(math.floor(x0)), 0), max(int(math.floor(y0)), 0)
        c1, r1 = min(int(math.ceil(x1)), w), min(int(math.ceil(y1)), h)
        sel[r0:r1, c0:c1] = mask[r0:r1, c0:c1]
        return sel
    cx, cy, hx, hy = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) * box_core / 2, (y1 - y0) * box_core / 2
    sel = np.zeros((h, w), bool)
    sel[max(int(cy - hy), 0):min(int(math.ceil(cy + hy)), h), max(int(cx - hx), 0):min(int(math.ceil(cx + hx)), w)] = True
    return sel


def pixels_to_world(depth_m: np.ndarray, intrinsics: np.ndarray, pose_wc: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """(N, 3) world points of the selected pixels (``pixels`` (H, W) bool) with their depths (z along
    the optical axis, OpenCV axes; pixel centres at integer coordinates), camera-to-world ``pose_wc``."""
    v, u = np.nonzero(pixels)
    z = depth_m[v, u].astype(np.float64)
    k = np.asarray(intrinsics, np.float64)
    cam = np.stack([(u - k[0, 2]) / k[0, 0] * z, (v - k[1, 2]) / k[1, 1] * z, z], axis=1)
    pose = np.asarray(pose_wc, np.float64)
    return cam @ pose[:3, :3].T + pose[:3, 3]


def localize(depth_m: np.ndarray, intrinsics: np.ndarray, pose_wc: np.ndarray, box_px, mask: np.ndarray | None = None,
             cfg: LocalizeCfg | None = None) -> np.ndarray | None:
    """(3,) the world point of one detection (module docstring), or None when too few of its pixels
    have a usable depth."""
    cfg = cfg or LocalizeCfg()
    depth = np.asarray(depth_m)
    sel = object_pixels(box_px, mask, depth.shape, cfg.box_core)
    sel &= np.isfinite(depth) & (depth > 0) & (depth < cfg.max_depth_m)
    if int(sel.sum()) < cfg.min_pixels:
        return None
    points = pixels_to_world(depth, intrinsics, pose_wc, sel)
    points = points[points[:, 2] >= cfg.min_height_m]
    if len(points) < cfg.min_pixels:
        return None
    return np.median(points, axis=0)


@dataclass
class ObjectTrack:
    label: str
    points_w: list[np.ndarray] = field(default_factory=list)
    """(3,) world points of its views."""
    scores: list[float] = field(default_factory=list)

    @property
    def point_w(self) -> np.ndarray:
        return np.median(np.asarray(self.points_w), axis=0)

    @property
    def views(self) -> int:
        return len(self.points_w)

    @property
    def score(self) -> float:
        return float(np.mean(self.scores))


@dataclass(kw_only=True)
class ObjectMapCfg(Checked):
    merge_radius_m: float = 0.7
    """A view within this of a track's point (in the floor plane) is that track's, m."""
    min_views: int = 3
    """Views a track needs to be a goal."""
    min_score: float = 0.4
    """Detections below this score are not fused."""


class ObjectMap:
    """Tracks of detected objects in the world frame (module docstring)."""

    def __init__(self, cfg: ObjectMapCfg | None = None):
        self.cfg = cfg or ObjectMapCfg()
        self.tracks: list[ObjectTrack] = []

    def add(self, label: str, point_w: np.ndarray, score: float) -> ObjectTrack | None:
        """Fuse one view; returns its track (None when its score is too low)."""
        if score < self.cfg.min_score:
            return None
        point_w = np.asarray(point_w, float)
        best, best_d = None, self.cfg.merge_radius_m
        for track in self.tracks:
            if track.label != label:
                continue
            d = float(np.linalg.norm(track.point_w[:2] - point_w[:2]))
            if d <= best_d:
                best, best_d = track, d
        if best is None:
            best = ObjectTrack(label)
            self.tracks.append(best)
        best.points_w.append(point_w)
        best.scores.append(float(score))
        return best

    def confirmed(self, label: str) -> list[ObjectTrack]:
        """Tracks of ``label`` with ``min_views`` views, most views first."""
        return sorted((t for t in self.tracks if t.label == label and t.views >= self.cfg.min_views),
                      key=lambda t: -t.views)


def standoff_goal(object_xy_m, robot_xy_m, grid: Grid2D, *, distance_range_m=(0.45, 0.8), clearance_m: float = 0.3,
                  reachable: np.ndarray | None = None, avoid_unknown: bool = True) -> tuple[np.ndarray, float] | None:
    """Where to stand to face an object at ``object_xy_m`` (its visible surface's point) and the yaw
    that faces it: the known-free cell of ``grid`` with ``clearance_m`` to any occupied or unknown
    cell, ``distance_range_m`` from the object, nearest to the robot (the side it was seen from);
    ``reachable`` (H, W) bool limits the cells further. None when there is none."""
    from scipy import ndimage

    occupied = grid.occupied() | grid.unknown() if avoid_unknown else grid.occupied()
    clear = ndimage.distance_transform_edt(~occupied) * grid.resolution_m - grid.resolution_m / 2
    ok = clear >= clearance_m
    if reachable is not None:
        ok &= reachable
    iy, ix = np.nonzero(ok)
    if not len(iy):
        return None
    xs, ys = grid.cell_center_xy_m(iy, ix)
    ox, oy = float(object_xy_m[0]), float(object_xy_m[1])
    d_obj = np.hypot(xs - ox, ys - oy)
    band = (d_obj >= distance_range_m[0]) & (d_obj <= distance_range_m[1])
    if not band.any():
        return None
    xs, ys = xs[band], ys[band]
    k = int(np.argmin(np.hypot(xs - robot_xy_m[0], ys - robot_xy_m[1])))
    goal = np.array([xs[k], ys[k]])
    return goal, math.atan2(oy - goal[1], ox - goal[0])


def wrap_rad(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


__all__ = ["LocalizeCfg", "ObjectMap", "ObjectMapCfg", "ObjectTrack", "localize", "object_pixels", "pixels_to_world",
           "standoff_goal", "wrap_rad"]
