"""Relocalisation against the navigator's own map: where does the current depth frame fit the 2-D
occupancy map built so far?

    scan = scan_xy_m(depth_m, intrinsics, pose_wc, cfg)        # the frame's points in the body band
    m = match_scan(grid, scan, pivot_xy_m, cfg, hypotheses=[legs_correction])
    if m.confident: pose = apply_correction(m.correction, pivot_xy_m, guess_xyyaw)

What the fused localizer (``localization.LegVoLocalizer``) asks when the VO and the legs disagree,
when a VO fix would be accepted after a bridge ran out, and now and then while tracked: the map is
the one witness independent of both odometries (it holds what earlier, accepted frames saw).

**Correlative scan matching** (Olson 2009, *Real-time correlative scan matching*, ICRA; the search
behind Cartographer's and Hector SLAM's relocalisation). The depth pixels whose world points lie in
the body band (walls, furniture, not the floor) are a 2-D scan. Every planar correction
(dx, dy, dyaw) of a window, turning the scan about ``pivot_xy_m`` (the camera) and shifting it, is
scored on a *likelihood field* of the map:

- ``exp(-d^2 / 2 hit_sigma_m^2)`` where ``d`` is the distance to the nearest surface cell (an
  occupied cell beside a non-occupied one: the inside of a solid the map holds is no surface);
- ``-free_penalty`` on observed-free cells farther than ``miss_m`` from any surface cell (the map
  saw through there: a surface in them contradicts it);
- 0 on unknown cells and deep inside solids (no evidence either way: a frame seeing past the
  map's edge is not punished).

The score is the mean over the scan's points. For each yaw step, the scores of every translation
are one cross-correlation of the field with the scan's point-count image (``scipy.signal``, FFT).

A match is **confident** when enough points hit (``min_hits``, ``min_score``) and it is unique: no
correction farther than ``ambiguity_m`` (or ``ambiguity_yaw_deg``) from the best scores within
``ambiguity_ratio`` of it. A bare wall or a corridor constrains only across it: its scores form a
ridge along it, and the match says so instead of picking a point on the ridge. Hypotheses (the
guess itself, the legs' pose) are scored too: one within ``confirm_ratio`` of the best is
*confirmed* and preferred over the best (the map's 5 cm cells do not tell apart poses that fit it
almost equally well). Where the window is ambiguous the map still tells two hypotheses apart when
one is confirmed and another *refuted* (below ``refute_ratio`` of the best): a corridor cannot say
where along it the robot is, but it can say that the VO's pose puts a wall in its free space.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage, signal

from ..maps import FREE, OCCUPIED, Grid2D
from ..utils.validate import Checked


@dataclass(kw_only=True)
class RelocalizeCfg(Checked):
    band_m: tuple[float, float] = (0.2, 1.5)
    """World heights of the scan's points, m: above the floor and low clutter (whose slice cells
    flicker), below the head."""
    max_depth_m: float = 4.0
    """Depth beyond this is left out, m (the mapper's TSDF stops there too)."""
    min_range_m: float = 0.3
    """Points nearer the camera than this (horizontally) are the robot's own hands, m."""
    pixel_stride: int = 4
    """Every this many pixels along each image axis (80 x 60 of the head camera's 320 x 240)."""
    max_normal_z: float = 0.5
    """Points whose surface normal has a larger vertical share than this (a top within 60 deg of
    level) are left out (``scan_xy_m``)."""
    search_xy_m: float = 0.5
    """The translation window reaches this far beyond the hypotheses' spread, m."""
    search_yaw_deg: float = 6.0
    """The yaw window reaches this far beyond the hypotheses' spread, deg."""
    yaw_step_deg: float = 1.0
    hit_sigma_m: float = 0.05
    """Width of a hit: the map's cell (5 cm); a surface lies between a free and an occupied cell."""
    miss_m: float = 0.15
    """An observed-free cell farther than this from occupied cells contradicts a point in it, m."""
    free_penalty: float = 1.0
    min_hits: int = 80
    """Points within ``miss_m`` of the map's occupied cells at the best correction."""
    min_score: float = 0.3
    """Mean field value at the best correction (1: every point on a wall of the map)."""
    ambiguity_ratio: float = 0.9
    ambiguity_m: float = 0.2
    ambiguity_yaw_deg: float = 4.0
    confirm_ratio: float = 0.95
    """A hypothesis scoring this share of the best is confirmed."""
    refute_ratio: float = 0.5
    """A hypothesis scoring less than this share of the best is refuted: on an ambiguous map (a
    corridor) a confirmed hypothesis is still chosen over a refuted one."""
    map_margin_m: float = 1.0
    """The field is computed over the scan's box grown by the window and this, m."""


@dataclass
class Match:
    """One ``match_scan`` result. Corrections are (dx m, dy m, dyaw rad): turn about the pivot by
    dyaw, then shift by (dx, dy) (``apply_correction``)."""

    correction: np.ndarray
    """(3,) the chosen correction: a confirmed hypothesis, else the best of the window."""
    best: np.ndarray
    """(3,) the window's best correction."""
    score: float
    hits: int
    points: int
    confident: bool
    reason: str
    """Why (not) confident: "ok", "told apart" (ambiguous, but one hypothesis confirmed and
    another refuted), "few points", "poor fit", "ambiguous"."""
    hypothesis_scores: list[float] = field(default_factory=list)
    """Score of each hypothesis given (the guess, the identity, first)."""
    chosen: int = -1
    """Index of the confirmed hypothesis (0: the guess), -1: the window's best."""


def scan_xy_m(depth_m: np.ndarray, intrinsics: np.ndarray, pose_wc: np.ndarray, cfg: RelocalizeCfg) -> np.ndarray:
    """(N, 2) world x, y of the frame's body-band points on steep surfaces with the camera at
    ``pose_wc`` (4, 4; OpenCV axes), m. ``depth_m`` (H, W) metres along the optical axis, 0 /
    non-finite: none. A point of a flat top (a bed, a table seen from above: its normal within
    ``max_normal_z`` of vertical) is left out: it lands inside the top's footprint, which the map
    holds solid, not on its outline."""
    s = cfg.pixel_stride
    depth = np.asarray(depth_m, np.float64)[::s, ::s]
    k = np.asarray(intrinsics, np.float64)
    v, u = np.mgrid[0:depth_m.shape[0]:s, 0:depth_m.shape[1]:s].astype(np.float64)
    ok = np.isfinite(depth) & (depth > 0) & (depth <= cfg.max_depth_m)
    z = np.where(ok, depth, np.nan)
    pts_c = np.stack([(u - k[0, 2]) / k[0, 0] * z, (v - k[1, 2]) / k[1, 1] * z, z], -1)  # (h, w, 3)
    pts_w = pts_c @ pose_wc[:3, :3].T + pose_wc[:3, 3]
    # normals from the neighbours (central differences; NaN at the border and beside holes)
    du = np.full_like(pts_w, np.nan)
    dv = np.full_like(pts_w, np.nan)
    du[:, 1:-1] = pts_w[:, 2:] - pts_w[:, :-2]
    dv[1:-1] = pts_w[2:] - pts_w[:-2]
    n = np.cross(du, dv)
    with np.errstate(invalid="ignore"):
        steep = np.abs(n[..., 2]) < cfg.max_normal_z * np.linalg.norm(n, axis=-1)
        keep = ok & steep & (pts_w[..., 2] >= cfg.band_m[0]) & (pts_w[..., 2] <= cfg.band_m[1])
        keep &= np.hypot(pts_w[..., 0] - pose_wc[0, 3], pts_w[..., 1] - pose_wc[1, 3]) >= cfg.min_range_m
    return pts_w[keep][:, :2]


def correction_between(from_xyyaw, to_xyyaw, pivot_xy_m) -> np.ndarray:
    """(3,) the correction (about ``pivot_xy_m``) that moves pose ``from_xyyaw`` onto ``to_xyyaw``."""
    a, b, p = np.asarray(from_xyyaw, float), np.asarray(to_xyyaw, float), np.asarray(pivot_xy_m, float)
    dyaw = math.atan2(math.sin(b[2] - a[2]), math.cos(b[2] - a[2]))
    return np.array([*(b[:2] - p - _rot(dyaw) @ (a[:2] - p)), dyaw])


def apply_correction(correction, pivot_xy_m, xyyaw) -> np.ndarray:
    """(3,) pose ``xyyaw`` (or (N, 2) points when given (N, 2)) moved by ``correction``."""
    c, p = np.asarray(correction, float), np.asarray(pivot_xy_m, float)
    x = np.asarray(xyyaw, float)
    if x.ndim == 2:
        return (x - p) @ _rot(c[2]).T + p + c[:2]
    yaw = x[2] + c[2]
    return np.array([*(_rot(c[2]) @ (x[:2] - p) + p + c[:2]), math.atan2(math.sin(yaw), math.cos(yaw))])


def match_scan(grid: Grid2D, scan_xy: np.ndarray, pivot_xy_m, cfg: RelocalizeCfg,
               hypotheses: list[np.ndarray] | tuple = ()) -> Match:
    """Score the corrections of the window around the guess (the identity) and ``hypotheses``
    (corrections, e.g. ``correction_between(guess, legs, pivot)``); module docstring."""
    scan = np.asarray(scan_xy, float).reshape(-1, 2)
    hyps = [np.zeros(3)] + [np.asarray(h, float) for h in hypotheses]
    n = len(scan)
    if n < cfg.min_hits:
        return Match(hyps[0], hyps[0], 0.0, 0, n, False, "few points")
    hx = np.array([h[0] for h in hyps])
    hy = np.array([h[1] for h in hyps])
    hyaw = np.array([h[2] for h in hyps])
    r = grid.resolution_m
    step = math.radians(cfg.yaw_step_deg)
    reach = math.radians(cfg.search_yaw_deg)
    yaws = np.arange(math.floor((hyaw.min() - reach) / step), math.ceil((hyaw.max() + reach) / step) + 1) * step
    kx = (math.floor((hx.min() - cfg.search_xy_m) / r), math.ceil((hx.max() + cfg.search_xy_m) / r))
    ky = (math.floor((hy.min() - cfg.search_xy_m) / r), math.ceil((hy.max() + cfg.search_xy_m) / r))
    field_, (fy0, fx0) = _field(grid, scan, pivot_xy_m, cfg, max(abs(k) for k in (*kx, *ky)) * r)
    pivot = np.asarray(pivot_xy_m, float)
    best = (-math.inf, 0.0, 0, 0)
    ridge = []  # per yaw: the translations' scores, for the ambiguity test
    for yaw in yaws:
        pts = (scan - pivot) @ _rot(yaw).T + pivot
        iy, ix = grid.cells_of(pts)
        iy, ix = iy - fy0, ix - fx0
        y0, x0 = iy.min(), ix.min()
        counts = np.zeros((iy.max() - y0 + 1, ix.max() - x0 + 1))
        np.add.at(counts, (iy - y0, ix - x0), 1.0)
        window = _crop(field_, y0 + ky[0], y0 + iy.max() - iy.min() + ky[1] + 1,
                       x0 + kx[0], x0 + ix.max() - ix.min() + kx[1] + 1)
        scores = signal.correlate(window, counts, mode="valid", method="fft") / n  # (ky, kx) translations
        j = np.unravel_index(int(np.argmax(scores)), scores.shape)
        ridge.append(scores)
        if scores[j] > best[0]:
            best = (float(scores[j]), float(yaw), int(j[0]) + ky[0], int(j[1]) + kx[0])
    score, yaw_b, ty, tx = best
    best_c = np.array([tx * r, ty * r, yaw_b])
    hits = _hits(field_, grid, scan, pivot, best_c, (fy0, fx0), cfg)
    hyp_scores = [_score(field_, grid, scan, pivot, h, (fy0, fx0), n) for h in hyps]
    if hits < cfg.min_hits:
        return Match(hyps[0], best_c, score, hits, n, False, "few points", hyp_scores)
    if score < cfg.min_score:
        return Match(hyps[0], best_c, score, hits, n, False, "poor fit", hyp_scores)
    confirmed = [i for i, s in enumerate(hyp_scores) if s >= cfg.confirm_ratio * score]
    if _ambiguous(ridge, yaws, (yaw_b, ty, tx), (ky[0], kx[0]), r, cfg.ambiguity_ratio * score, cfg):
        refuted = [i for i, s in enumerate(hyp_scores) if s < cfg.refute_ratio * score]
        if confirmed and refuted:  # the map cannot place the robot, but it tells the hypotheses apart
            return Match(hyps[confirmed[0]], best_c, score, hits, n, True, "told apart", hyp_scores, confirmed[0])
        return Match(hyps[0], best_c, score, hits, n, False, "ambiguous", hyp_scores)
    if confirmed:
        return Match(hyps[confirmed[0]], best_c, score, hits, n, True, "ok", hyp_scores, confirmed[0])
    return Match(best_c, best_c, score, hits, n, True, "ok", hyp_scores, -1)


def _ambiguous(ridge, yaws, best, k0, r: float, near: float, cfg: RelocalizeCfg) -> bool:
    """Whether a correction far from the best (``ambiguity_m`` / ``ambiguity_yaw_deg``) scores
    ``near`` or more."""
    yaw_b, ty, tx = best
    for yaw, scores in zip(yaws, ridge, strict=True):
        jy, jx = np.nonzero(scores >= near)
        if not len(jy):
            continue
        if abs(yaw - yaw_b) > math.radians(cfg.ambiguity_yaw_deg):
            return True
        if np.hypot((jx + k0[1] - tx) * r, (jy + k0[0] - ty) * r).max() > cfg.ambiguity_m:
            return True
    return False


def look_yaw_rad(grid: Grid2D, xy_m, cfg: RelocalizeCfg, fov_deg: float = 62.0, min_range_m: float = 0.8,
                 rays: int = 360) -> float | None:
    """The heading (world yaw, rad) whose view (``fov_deg`` wide, up to ``cfg.max_depth_m``) holds
    the most mapped surfaces at ``min_range_m`` or more, and among equals the widest spread of
    ranges (corners and furniture constrain a match in every direction; one bare wall does not):
    where a lost robot turns to relocalise (``match_scan`` needs mapped surfaces in view). None
    when no ray meets a mapped surface. ``fov_deg``: the head camera's 62 deg (320 px at 262.5 px
    focal length)."""
    angles = np.arange(rays) * (2 * math.pi / rays)
    r = grid.resolution_m
    steps = np.arange(1, int(cfg.max_depth_m / (0.5 * r)) + 1) * 0.5 * r  # half-cell steps along each ray
    pts = np.asarray(xy_m, float)[None, None, :] + steps[None, :, None] * np.stack([np.cos(angles), np.sin(angles)], -1)[:, None, :]
    iy, ix = grid.cells_of(pts.reshape(-1, 2))
    ny, nx = grid.shape
    inside = (iy >= 0) & (iy < ny) & (ix >= 0) & (ix < nx)
    occ = np.full(len(iy), FREE - 1, np.int16)
    occ[inside] = grid.occupancy[iy[inside], ix[inside]]
    occ = occ.reshape(rays, len(steps))
    hit = occ >= OCCUPIED
    first = np.where(hit.any(1), hit.argmax(1), -1)
    range_m = np.where(first >= 0, steps[np.maximum(first, 0)], np.nan)
    seen = (first >= 0) & (range_m >= min_range_m)
    # a ray whose cells before the hit are all unknown did not come from the map's seen space
    known_before = np.array([first[i] <= 0 or (occ[i, :first[i]] >= FREE).mean() > 0.5 for i in range(rays)])
    seen &= known_before
    if not seen.any():
        return None
    half = int(round(0.5 * fov_deg / 360 * rays))
    window = np.arange(-half, half + 1)
    idx = (np.arange(rays)[:, None] + window[None, :]) % rays
    counts = seen[idx].sum(1)
    ranges = np.where(seen[idx], range_m[idx], np.nan)
    with np.errstate(invalid="ignore"):
        spread = np.nan_to_num(np.nanstd(ranges, axis=1))
    best = np.lexsort((spread, counts))[-1]
    return float(math.atan2(math.sin(angles[best]), math.cos(angles[best])))


def _rot(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def _field(grid: Grid2D, scan: np.ndarray, pivot, cfg: RelocalizeCfg, reach_m: float):
    """The likelihood field (module docstring) over the box of the scan (turned about the pivot by
    any yaw: the box of its farthest point's circle) grown by ``reach_m`` and the margin; returns it
    and the grid cell (iy, ix) of its [0, 0]."""
    radius = float(np.hypot(*(scan - np.asarray(pivot)).T).max()) + reach_m + cfg.map_margin_m
    (iy0, ix0), (iy1, ix1) = grid.cell_of(np.asarray(pivot) - radius), grid.cell_of(np.asarray(pivot) + radius)
    occ = _crop(grid.occupancy.astype(np.int16), iy0, iy1 + 1, ix0, ix1 + 1, fill=-1)
    occupied = occ >= OCCUPIED
    surface = occupied & ndimage.binary_dilation(~occupied)  # occupied cells beside a non-occupied one
    if surface.any():
        dist_m = ndimage.distance_transform_edt(~surface) * grid.resolution_m
    else:
        dist_m = np.full(occ.shape, np.inf)
    out = np.exp(-0.5 * (dist_m / cfg.hit_sigma_m) ** 2)
    # a surface seen in free space contradicts the map; deep inside a solid the map holds (a wall's
    # core, under a top) or in unknown space it is no evidence either way
    out[(occ >= FREE) & (occ < OCCUPIED) & (dist_m > cfg.miss_m)] = -cfg.free_penalty
    out[((occ < FREE) | (occ >= OCCUPIED)) & (dist_m > cfg.miss_m)] = 0.0
    return out, (iy0, ix0)


def _crop(a: np.ndarray, y0: int, y1: int, x0: int, x1: int, fill=0.0) -> np.ndarray:
    """``a[y0:y1, x0:x1]`` with ``fill`` outside ``a``."""
    out = np.full((y1 - y0, x1 - x0), fill, a.dtype)
    sy0, sy1, sx0, sx1 = max(y0, 0), min(y1, a.shape[0]), max(x0, 0), min(x1, a.shape[1])
    if sy0 < sy1 and sx0 < sx1:
        out[sy0 - y0:sy1 - y0, sx0 - x0:sx1 - x0] = a[sy0:sy1, sx0:sx1]
    return out


def _lookup(field_, grid, scan, pivot, correction, origin) -> np.ndarray:
    iy, ix = grid.cells_of(apply_correction(correction, pivot, scan))
    iy, ix = iy - origin[0], ix - origin[1]
    inside = (iy >= 0) & (iy < field_.shape[0]) & (ix >= 0) & (ix < field_.shape[1])
    out = np.zeros(len(iy))
    out[inside] = field_[iy[inside], ix[inside]]
    return out


def _score(field_, grid, scan, pivot, correction, origin, n: int) -> float:
    return float(_lookup(field_, grid, scan, pivot, correction, origin).sum() / n)


def _hits(field_, grid, scan, pivot, correction, origin, cfg: RelocalizeCfg) -> int:
    return int((_lookup(field_, grid, scan, pivot, correction, origin) >= math.exp(-0.5 * (cfg.miss_m / cfg.hit_sigma_m) ** 2)).sum())


__all__ = ["Match", "RelocalizeCfg", "apply_correction", "correction_between", "look_yaw_rad", "match_scan", "scan_xy_m"]
