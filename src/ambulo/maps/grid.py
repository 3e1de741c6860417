"""``Grid2D``: the one 2-D grid map of ambulo, with ROS's cell convention, and ``CellGeometry``,
the cell <-> world arithmetic every 2-D map shares (perception's slices and costmap, the
footstep planner's ``GridMap``).

The convention (``nav_msgs/OccupancyGrid``, map_server, Nav2's costmaps)::

    origin_xy_m = (ox, oy)  world (x, y) of the lower-left CORNER of cell [0, 0], m
    resolution_m = r        side of a square cell, m
    values[iy, ix]          row iy = y, column ix = x; row 0 holds the LOWEST y (y up, as
                            seen from above), so an image file's rows are flipped
    cell [iy, ix] covers    x in [ox + ix r, ox + (ix + 1) r),  y in [oy + iy r, oy + (iy + 1) r)
    its centre              (ox + (ix + 0.5) r, oy + (iy + 0.5) r)

The map is axis-aligned: a map_server ``origin`` yaw or an OccupancyGrid origin rotation other
than zero is refused when loaded (nothing in ambulo draws or plans on a rotated grid; most of
ROS ignores that yaw too).

Values are ``OccupancyGrid.data``'s: ``UNKNOWN`` (-1), ``FREE`` (0) .. ``OCCUPIED`` (100), an
occupancy probability in percent. A trinary map holds only -1, 0 and 100. An optional cost layer
holds Nav2's costmap costs (``nav2_costmap_2d/cost_values.hpp``) over the same cells.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from ..utils.checks import Described, InvalidValueError, check_positive, check_vector

UNKNOWN, FREE, OCCUPIED = -1, 0, 100
"""``nav_msgs/OccupancyGrid.data`` values (``nav2_util/occ_grid_values.hpp``): unknown, free,
occupied; values between FREE and OCCUPIED are an occupancy probability in percent."""

FREE_SPACE, INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION = 0, 253, 254, 255
"""Nav2's costmap costs (``nav2_costmap_2d/cost_values.hpp``); 1..252 decay with the distance
to the nearest obstacle."""


class CellGeometry:
    """World <-> cell arithmetic of a grid with ``origin_xy_m`` (lower-left corner of cell [0, 0]),
    ``resolution_m`` and ``shape`` (num_y, num_x): the one place the convention is written down."""

    origin_xy_m: tuple[float, float]
    resolution_m: float
    shape: tuple[int, ...]

    def cell_center_xy_m(self, iy, ix):
        """World (x, y) of the centre of cell [iy, ix], m (ints or integer arrays of one shape)."""
        (ox, oy), r = self.origin_xy_m, self.resolution_m
        return ox + (np.asarray(ix) + 0.5) * r, oy + (np.asarray(iy) + 0.5) * r

    def cell_rect_xy_m(self, iy: int, ix: int) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max): the world rectangle cell [iy, ix] covers, m."""
        (ox, oy), r = self.origin_xy_m, self.resolution_m
        return (ox + ix * r, oy + iy * r, ox + (ix + 1) * r, oy + (iy + 1) * r)

    def cell_of(self, xy_m) -> tuple[int, int]:
        """(iy, ix) of the cell holding world point (x, y) (possibly outside the map; a point on
        a cell border belongs to the cell above/right of it)."""
        (ox, oy), r = self.origin_xy_m, self.resolution_m
        return int(math.floor((float(xy_m[1]) - oy) / r)), int(math.floor((float(xy_m[0]) - ox) / r))

    def cells_of(self, xy_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(iy, ix), each (N,) int64: the cells holding world points ``xy_m`` (N, 2), m."""
        xy = np.asarray(xy_m, np.float64).reshape(-1, 2)
        (ox, oy), r = self.origin_xy_m, self.resolution_m
        return np.floor((xy[:, 1] - oy) / r).astype(np.int64), np.floor((xy[:, 0] - ox) / r).astype(np.int64)

    def cell_centers_xy_m(self) -> np.ndarray:
        """(num_y, num_x, 2) float64 world (x, y) of every cell centre, m."""
        num_y, num_x = self.shape[:2]
        xs, ys = self.cell_center_xy_m(np.arange(num_y), np.arange(num_x))
        return np.stack(np.meshgrid(xs, ys, indexing="xy"), axis=-1)

    def extent_xy_m(self) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max): the world rectangle the whole map covers, m."""
        num_y, num_x = self.shape[:2]
        x0, y0, _, _ = self.cell_rect_xy_m(0, 0)
        _, _, x1, y1 = self.cell_rect_xy_m(num_y - 1, num_x - 1)
        return x0, y0, x1, y1


def check_yaw_zero(what: str, yaw_rad: float) -> None:
    """Refuse a rotated map origin in one line (ambulo's maps are axis-aligned)."""
    if abs(yaw_rad) > 1e-9:
        raise InvalidValueError(what, yaw_rad, "ambulo's 2-D maps are axis-aligned (origin yaw 0)",
                                "rotate the map image instead, or set the yaw to 0")


def _to_numpy(array) -> np.ndarray:
    return array.detach().cpu().numpy() if isinstance(array, torch.Tensor) else np.asarray(array)


@dataclass(frozen=True, eq=False, kw_only=True)
class Grid2D(CellGeometry):
    """A 2-D occupancy map (and optionally a Nav2 cost layer) in the world x-y plane."""

    occupancy: np.ndarray
    """(num_y, num_x) int8 ``OccupancyGrid.data`` values: UNKNOWN (-1), FREE (0) .. OCCUPIED (100)."""
    origin_xy_m: tuple[float, float]
    """World (x, y) of the lower-left corner of cell [0, 0], m."""
    resolution_m: float
    """Side of a square cell, m."""
    cost: np.ndarray | None = None
    """(num_y, num_x) uint8 Nav2 costs (FREE_SPACE, 1..252 decaying, INSCRIBED_INFLATED_OBSTACLE,
    LETHAL_OBSTACLE, NO_INFORMATION) of the same cells, or None."""

    def __post_init__(self) -> None:
        occ = self.occupancy
        if not isinstance(occ, np.ndarray) or occ.ndim != 2 or occ.dtype != np.int8 or occ.size == 0:
            raise InvalidValueError("Grid2D.occupancy", Described(_describe(occ)),
                                    "expected a non-empty 2-D int8 array (num_y, num_x) of -1 or 0..100",
                                    "build it with Grid2D.from_masks, or convert with .astype(np.int8)")
        if ((occ < UNKNOWN) | (occ > OCCUPIED)).any():
            raise InvalidValueError("Grid2D.occupancy", Described(f"in [{occ.min()}, {occ.max()}]"),
                                    "values must be -1 (unknown) or 0..100 (occupancy %)",
                                    "map unknown cells to -1 and probabilities to percent")
        check_vector("Grid2D.origin_xy_m", self.origin_xy_m, 2, "pass the lower-left corner of cell [0, 0] as (x, y) in m")
        check_positive("Grid2D.resolution_m", self.resolution_m, "pass the cell side in m, e.g. 0.05")
        if self.cost is not None and (not isinstance(self.cost, np.ndarray) or self.cost.dtype != np.uint8
                                      or self.cost.shape != occ.shape):
            raise InvalidValueError("Grid2D.cost", Described(_describe(self.cost)),
                                    f"expected a uint8 array of the occupancy's shape {occ.shape}",
                                    "pass Nav2 costs 0..255 per cell, or None")

    @classmethod
    def from_masks(cls, occupied, *, unknown=None, origin_xy_m, resolution_m: float, cost=None) -> Grid2D:
        """A trinary map from (num_y, num_x) masks (numpy or torch, bool or 0/1): OCCUPIED where
        ``occupied``, else UNKNOWN where ``unknown``, else FREE; ``cost`` any uint8-valued array."""
        occ = _to_numpy(occupied).astype(bool)
        values = np.where(occ, np.int8(OCCUPIED), np.int8(FREE)).astype(np.int8)
        if unknown is not None:
            values[_to_numpy(unknown).astype(bool) & ~occ] = UNKNOWN
        if cost is not None:
            cost = _to_numpy(cost).astype(np.uint8)
        origin = tuple(float(v) for v in check_vector("origin_xy_m", origin_xy_m, 2, "pass (x, y) in m"))
        return cls(occupancy=values, origin_xy_m=origin, resolution_m=float(resolution_m), cost=cost)

    @property
    def shape(self) -> tuple[int, int]:
        """(num_y, num_x)."""
        return self.occupancy.shape

    def unknown(self) -> np.ndarray:
        """(num_y, num_x) bool: never observed."""
        return self.occupancy == UNKNOWN

    def occupied(self, min_percent: int = OCCUPIED) -> np.ndarray:
        """(num_y, num_x) bool: occupancy >= ``min_percent`` (100 = Nav2's static layer's default
        ``lethal_threshold``; lower it for a scale-mode map)."""
        return self.occupancy >= min_percent

    def free(self, min_percent: int = OCCUPIED) -> np.ndarray:
        """(num_y, num_x) bool: known and below ``min_percent``."""
        return (self.occupancy >= FREE) & (self.occupancy < min_percent)

    def blocked(self, min_percent: int = OCCUPIED) -> np.ndarray:
        """(num_y, num_x) bool: occupied or unknown, where a robot that must not walk into the
        unseen may not go (Nav2's ``allow_unknown: false``)."""
        return self.occupied(min_percent) | self.unknown()


def _describe(array) -> str:
    if isinstance(array, (np.ndarray, torch.Tensor)):
        return f"a {array.dtype} array of shape {tuple(array.shape)}"
    return f"a {type(array).__name__}"


__all__ = ["FREE", "FREE_SPACE", "INSCRIBED_INFLATED_OBSTACLE", "LETHAL_OBSTACLE", "NO_INFORMATION", "OCCUPIED",
           "UNKNOWN", "CellGeometry", "Grid2D", "check_yaw_zero"]
