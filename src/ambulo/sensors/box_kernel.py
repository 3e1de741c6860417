"""The loose 2D and the 3D boxes' per-corner steps in one compiled loop each (numba), NumPy without it.

``annotators.loose_box_array`` and ``instance_boxes_3d`` spend most of their time on ~25 small NumPy
calls after the geometry's matrix products (near-plane cuts of the 12 box edges, projection, masked
minima and maxima, reductions per instance): ~50 of a frame's ~100 us hot at 320x240. These kernels do
those steps in one pass with the same IEEE operations in the same order, so they give the NumPy path's
floats bit for bit (``tests/sensors/test_box_kernel.py``); a dataset is the same with and without numba.
The matrix products themselves stay NumPy's (``@`` and ``einsum``): BLAS and einsum sum their three
terms in an order (and with fused multiply-adds) a plain loop does not repeat.

numba is optional (the ``data`` extra). The annotators take these kernels only once ``warm_up`` has
loaded them (``active``): a dataset producer calls it while it builds its scene, so a camera used
elsewhere (a script's few captures) never pays numba's import and a compile (~0.5-2 s) for ~50 us a
frame. ``AMBULO_NUMBA=0`` takes the NumPy path on purpose (``utils.compiled``, which compiles these
kernels as it does the replicator's).
"""

from __future__ import annotations

import numpy as np

from ambulo.utils.compiled import HAVE_NUMBA, Kernel

_EDGE_A = np.array([0, 0, 0, 1, 1, 2, 2, 3, 4, 4, 5, 6], np.int64)
_EDGE_B = np.array([1, 2, 4, 3, 5, 3, 6, 7, 5, 6, 7, 7], np.int64)
"""The 12 edges of ``annotators._CUBE``'s corners (x, y, z in {-1, 1}, z fastest), as corner pairs, in
``annotators._EDGES``' order."""


def _loose_py(corners_c, starts, near_m, k4, limits):
    """Per instance, the loose box of its geoms' corners ``corners_c`` (G, 8, 3) in the camera frame (m).

    ``starts`` (n,) int64: where each instance's geoms begin (ascending; the last runs to G); ``k4``
    (fx, fy, cx, cy) px; ``limits`` (width - 0.5, height - 0.5) px. Returns (n, 4) float64 [x_min, y_min,
    x_max, y_max], clipped to the image, as ``loose_box_array`` computes them before it keeps the
    instances in view. Each point's numbers are those of ``annotators._near_clipped`` and the projection
    there: the 8 corners in front of the near plane, and where each edge crossing it cuts it,
    a + t (b - a) with t = (near - z_a) / (z_b - z_a).
    """
    g_count = corners_c.shape[0]
    n = starts.shape[0]
    fx, fy, cx, cy = k4[0], k4[1], k4[2], k4[3]
    geom_lo = np.empty((g_count, 2))
    geom_hi = np.empty((g_count, 2))
    point = np.empty(3)
    for g in range(g_count):
        lo_u, lo_v, hi_u, hi_v = np.inf, np.inf, -np.inf, -np.inf
        for k in range(20):
            if k < 8:
                point[0], point[1], point[2] = corners_c[g, k, 0], corners_c[g, k, 1], corners_c[g, k, 2]
                valid = point[2] >= near_m
            else:
                a, b = _EDGE_A[k - 8], _EDGE_B[k - 8]
                za, zb = corners_c[g, a, 2], corners_c[g, b, 2]
                valid = (za - near_m) * (zb - near_m) < 0
                t = (near_m - za) / (zb - za) if valid else 0.0
                for j in range(3):
                    point[j] = corners_c[g, a, j] + t * (corners_c[g, b, j] - corners_c[g, a, j])
            if not valid:
                continue
            u = point[0] / point[2] * fx + cx
            v = point[1] / point[2] * fy + cy
            # as np.minimum / np.maximum: a NaN, once met, is the result
            lo_u = lo_u if (lo_u <= u or lo_u != lo_u) else u
            lo_v = lo_v if (lo_v <= v or lo_v != lo_v) else v
            hi_u = hi_u if (hi_u >= u or hi_u != hi_u) else u
            hi_v = hi_v if (hi_v >= v or hi_v != hi_v) else v
        geom_lo[g, 0], geom_lo[g, 1], geom_hi[g, 0], geom_hi[g, 1] = lo_u, lo_v, hi_u, hi_v
    boxes = np.empty((n, 4))
    for i in range(n):
        end = starts[i + 1] if i + 1 < n else g_count
        for j in range(2):
            lo, hi = geom_lo[starts[i], j], geom_hi[starts[i], j]
            for g in range(starts[i] + 1, end):
                lo = lo if (lo <= geom_lo[g, j] or lo != lo) else geom_lo[g, j]
                hi = hi if (hi >= geom_hi[g, j] or hi != hi) else geom_hi[g, j]
            boxes[i, j] = lo if (lo >= -0.5 or lo != lo) else -0.5  # np.maximum(lo, -0.5), NaN kept
            boxes[i, 2 + j] = hi if (hi <= limits[j] or hi != hi) else limits[j]  # np.minimum
    return boxes


def _extents_py(local, starts):
    """Per instance, the minimum and maximum (n, 3) of its geoms' corners ``local`` (G, 8, 3) along each
    axis: ``np.minimum.reduceat(local.min(1), starts)`` and the maximum's."""
    g_count = local.shape[0]
    n = starts.shape[0]
    lo = np.empty((n, 3))
    hi = np.empty((n, 3))
    for i in range(n):
        end = starts[i + 1] if i + 1 < n else g_count
        for j in range(3):
            low, high = local[starts[i], 0, j], local[starts[i], 0, j]
            for g in range(starts[i], end):
                for c in range(8):
                    x = local[g, c, j]
                    low = low if (low <= x or low != low) else x
                    high = high if (high >= x or high != high) else x
            lo[i, j], hi[i, j] = low, high
    return lo, hi


_loose = Kernel(_loose_py)
_extents = Kernel(_extents_py)


def loose_boxes_of_corners(corners_c: np.ndarray, starts: np.ndarray, near_m: float, k_matrix: np.ndarray,
                           width: int, height: int) -> np.ndarray:
    """(n, 4) ``_loose_py`` compiled: each instance's loose box from its geoms' corners (G, 8, 3) in the
    camera frame, clipped to the image (before dropping the instances out of view)."""
    k4 = np.array((k_matrix[0, 0], k_matrix[1, 1], k_matrix[0, 2], k_matrix[1, 2]), np.float64)
    limits = np.array((width - 0.5, height - 0.5), np.float64)
    return _loose(np.ascontiguousarray(corners_c, np.float64), np.ascontiguousarray(starts, np.int64),
                  float(near_m), k4, limits)


def extents_of_corners(local: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``_extents_py`` compiled: per instance, the (n, 3) minimum and maximum of its geoms' corners."""
    return _extents(np.ascontiguousarray(local, np.float64), np.ascontiguousarray(starts, np.int64))


_active = False


def active() -> bool:
    """Whether the annotators use the kernels: numba is there and ``warm_up`` has loaded them."""
    return _active


def warm_up() -> None:
    """Compile the kernels, or load them from numba's cache, now rather than in a first frame; from then on
    the annotators use them (``active``)."""
    global _active
    if HAVE_NUMBA:
        corners = np.ones((1, 8, 3))
        loose_boxes_of_corners(corners, np.zeros(1, np.int64), 0.1, np.eye(3), 2, 2)
        extents_of_corners(corners, np.zeros(1, np.int64))
        _active = True
