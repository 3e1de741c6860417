"""Where a grid of worlds is drawn: every world of a batch sits at the same place in the simulation
(``mujoco.batch`` and MuJoCo Warp keep N copies of one model, no env spacing), so the viewer
offsets each drawn world in the page, on a near-square grid.

Slot 0 (the watched world) stays at the origin, so its bodies and every overlay are drawn where
the simulation says; slot k sits at column k % cols, row k // cols, ``spacing_m`` apart along +x
and +y (the page's default camera looks from -x, -y, so the grid spreads away from it).
"""

from __future__ import annotations

import math

import numpy as np

from .geometry import GeomShape, is_ground

MIN_SPACING_M = 3.0
"""Closest two drawn worlds sit: a robot alone is about a metre wide, and a walking one leaves its
start by a metre in a few seconds."""
MARGIN_M = 1.0
"""Gap between two worlds' scenes, m."""
GRID_SIZES = (1, 4, 9, 16)
"""Worlds the page offers to draw at once."""


def grid_offsets_w(count: int, spacing_m: float) -> np.ndarray:
    """(count, 3) offsets of the drawn worlds in the page, world frame, m; row 0 is zero."""
    if count < 1:
        raise ValueError(f"count is {count}: draw at least one world")
    cols = math.ceil(math.sqrt(count))
    k = np.arange(count)
    return np.stack([(k % cols) * spacing_m, (k // cols) * spacing_m, np.zeros(count)], axis=1)


def scene_spacing_m(shapes: list[GeomShape], xpos_w: np.ndarray, xmat_w: np.ndarray) -> float:
    """Spacing of the grid: the larger horizontal extent of the scene's shapes other than ground
    planes (``geometry.is_ground``) (posed by ``xpos_w`` (nbody, 3) and ``xmat_w`` (nbody, 3, 3)) plus ``MARGIN_M``, at
    least ``MIN_SPACING_M``: an apartment's walls do not overlap the next world's."""
    points = [shape.vertices_b @ xmat_w[shape.body_id].T + xpos_w[shape.body_id]
              for shape in shapes if not is_ground(shape)]
    if not points:
        return MIN_SPACING_M
    xy = np.concatenate(points)[:, :2]
    span_m = float((xy.max(axis=0) - xy.min(axis=0)).max())
    return max(MIN_SPACING_M, span_m + MARGIN_M)
