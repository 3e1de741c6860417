"""Guided matching: each keypoint is compared only with the map points that the predicted pose
projects near it (ORB-SLAM's search by projection, Mur-Artal et al. 2015), not with the whole
local map.

Why: with 1500 ORB keypoints against a local map of three keyframes (~4000 points) the brute-force
Hamming k-NN (OpenCV's ``BFMatcher.knnMatch``) compares 6 million pairs a frame and was half of the
navigator's odometry time (152 ms of 287 a frame in a full-mode episode on a busy 2-core machine,
``benchmarks/nav_vo.py``). Within ``VoCfg.match_window_px`` of the prediction a keypoint has a few
dozen candidates. Lowe's ratio test and the Hamming limit are applied among those candidates, as
the brute force applies them among all map points; a keypoint with one candidate has no second
best and passes on the Hamming limit alone.

``window_pairs`` finds the candidate pairs with a uniform grid over the image (cell side = the
window): each keypoint reads the 3 x 3 cells around its own (three runs of the map points sorted by
cell), and the pairs are exact (distance <= window). ``best_two`` reduces per-pair distances to each keypoint's nearest and second nearest in
one pass over the pairs (they come grouped by keypoint). All numpy, on the host: ORB and its
matcher live there (``vo.features.OrbFeatures``).
"""

from __future__ import annotations

import numpy as np


def window_pairs(query_px: np.ndarray, map_px: np.ndarray, window_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs ``(q (P,), m (P,))`` of keypoints ``query_px`` (N, 2) and map projections ``map_px``
    (M, 2) (px; rows with a non-finite coordinate are never paired) at most ``window_px`` apart,
    grouped by ``q`` in increasing order."""
    query_px = np.asarray(query_px, np.float64).reshape(-1, 2)
    map_px = np.asarray(map_px, np.float64).reshape(-1, 2)
    empty = np.zeros(0, np.int64)
    usable = np.flatnonzero(np.isfinite(map_px).all(1))
    if not len(query_px) or not len(usable):
        return empty, empty
    # a grid of cells of the window's side over the keypoints' box grown by one cell each way, so
    # every keypoint's 3 x 3 cells are on it; map points outside it can pair with no keypoint
    lo = query_px.min(0) - window_px
    nx, ny = np.floor((query_px.max(0) + window_px - lo) / window_px).astype(np.int64) + 1
    cell_m = np.floor((map_px[usable] - lo) / window_px)
    inside = (cell_m >= 0).all(1) & (cell_m[:, 0] < nx) & (cell_m[:, 1] < ny)
    usable, cell_m = usable[inside], cell_m[inside].astype(np.int64)
    # map points sorted by cell (CSR): cell c holds order[first[c] : first[c + 1]]
    ids = cell_m[:, 1] * nx + cell_m[:, 0]
    order = usable[np.argsort(ids, kind="stable")]
    first = np.concatenate([[0], np.cumsum(np.bincount(ids, minlength=nx * ny))])
    # a keypoint's three cells in a row are consecutive in that order: one run per row
    cell_q = np.floor((query_px - lo) / window_px).astype(np.int64)
    left = (cell_q[:, 1, None] + np.array([-1, 0, 1])) * nx + cell_q[:, 0, None] - 1  # (N, 3) each row's first cell
    run_first, run_len = first[left].ravel(), (first[left + 3] - first[left]).ravel()
    total = int(run_len.sum())
    if not total:
        return empty, empty
    q = np.repeat(np.arange(len(query_px)), run_len.reshape(-1, 3).sum(1))
    m = order[np.repeat(run_first - (np.cumsum(run_len) - run_len), run_len) + np.arange(total)]
    dx, dy = query_px[q, 0] - map_px[m, 0], query_px[q, 1] - map_px[m, 1]
    near = dx * dx + dy * dy <= window_px**2
    return q[near], m[near]


def hamming(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(P,) bit distances between rows of ``a`` and ``b`` (P, D) uint8, D a multiple of 8."""
    x = np.bitwise_xor(np.ascontiguousarray(a).view(np.uint64), np.ascontiguousarray(b).view(np.uint64))
    return np.bitwise_count(x).sum(1, dtype=np.int64)


def best_two(q: np.ndarray, dist: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per query with candidates: ``(query (K,), best pair index (K,), second best distance (K,))``
    (inf where a query has one candidate), from pairs grouped by ``q`` in increasing order."""
    if not len(q):
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    starts = np.flatnonzero(np.r_[True, q[1:] != q[:-1]])
    group = np.repeat(np.arange(len(starts)), np.diff(np.r_[starts, len(q)]))
    d = dist.astype(np.float64)
    low = np.minimum.reduceat(d, starts)
    at_low = np.flatnonzero(d == low[group])  # grouped, so each group's first is its best
    best = at_low[np.r_[True, group[at_low][1:] != group[at_low][:-1]]]
    d[best] = np.inf
    return q[starts], best, np.minimum.reduceat(d, starts)
