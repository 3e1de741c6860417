"""A Nav2 inflation costmap from an occupancy slice, for a humanoid's footprint.

Cost of a cell at Euclidean distance d (cell centre to the nearest obstacle cell centre, in
cells; r = resolution), exactly as Nav2's ``InflationLayer::computeCost``
(``nav2_costmap_2d/include/nav2_costmap_2d/inflation_layer.hpp``)::

    d == 0                    -> LETHAL_OBSTACLE (254)
    d * r <= inscribed_radius -> INSCRIBED_INFLATED_OBSTACLE (253)
    otherwise                 -> uint8(252 * exp(-cost_scaling_factor * (d * r - inscribed_radius)))

(note 252 = INSCRIBED - 1, truncated toward zero), for cells with d <= ceil(inflation_radius / r)
(Nav2's ``cell_inflation_radius_``) and 0 beyond. Unknown cells stay NO_INFORMATION (255) unless
the inflation reaches them with at least the inscribed cost (Nav2's ``inflate_unknown: false``).
The inscribed radius is the footprint's: for the humanoid, the largest circle inside its standing
footprint (``HUMANOID_FOOTPRINT_XY_M``), ``HUMANOID_INSCRIBED_RADIUS_M``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from ambulo.maps import FREE_SPACE, INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION
from ambulo.maps.occupancy_grid import cost_to_occupancy, grid_info
from ambulo.robots import humanoid
from ambulo.utils.checks import check_positive
from ambulo.utils.validate import Checked

from .esdf import edt
from .slices import OCCUPIED, UNKNOWN, Slice2D
from .torch_threads import one_torch_thread

HUMANOID_FOOTPRINT_XY_M = ((0.11, 0.24), (0.11, -0.24), (-0.11, -0.24), (-0.11, 0.24))
"""The bundled humanoid standing, seen from above (humanoid.xml): feet 0.22 m long; upper arms at
y = +-0.20 m with 0.04 m capsules, so 0.48 m across the shoulders."""

HUMANOID_INSCRIBED_RADIUS_M = 0.11
"""Largest circle inside ``HUMANOID_FOOTPRINT_XY_M`` (half its 0.22 m depth): Nav2's inscribed radius."""

HUMANOID_CIRCUMSCRIBED_RADIUS_M = humanoid.BODY_RADIUS_M
"""Circle around the footprint (hypot(0.11, 0.24) m, rounded up): the body radius of ``robots.humanoid``."""


@dataclass(kw_only=True)
class InflationCfg(Checked):
    """Nav2's inflation layer parameters, with the humanoid's radii as defaults."""

    inflation_radius_m: float = 0.55
    """Nav2's default ``inflation_radius``."""
    cost_scaling_factor: float = 10.0
    """Nav2's default ``cost_scaling_factor``, 1/m."""
    inscribed_radius_m: float = HUMANOID_INSCRIBED_RADIUS_M
    inflate_unknown: bool = False

    def __post_init__(self):
        check_positive("inflation_radius_m", self.inflation_radius_m, "pass metres > 0, e.g. 0.55")
        check_positive("cost_scaling_factor", self.cost_scaling_factor, "pass 1/m > 0, e.g. 10", allow_zero=True)
        check_positive("inscribed_radius_m", self.inscribed_radius_m, "pass metres >= 0", allow_zero=True)
        super().__post_init__()


def nav2_cost(distance_cells: torch.Tensor, resolution_m: float, cfg: InflationCfg) -> torch.Tensor:
    """Nav2's ``computeCost`` on a tensor of distances in cells (float), as uint8."""
    d_m = distance_cells.to(torch.float64) * resolution_m
    decay = (INSCRIBED_INFLATED_OBSTACLE - 1) * torch.exp(-cfg.cost_scaling_factor * (d_m - cfg.inscribed_radius_m))
    cost = torch.where(d_m <= cfg.inscribed_radius_m, torch.full_like(d_m, INSCRIBED_INFLATED_OBSTACLE),
                       torch.floor(decay))
    cost = torch.where(distance_cells == 0, torch.full_like(d_m, LETHAL_OBSTACLE), cost)
    cell_radius = math.ceil(cfg.inflation_radius_m / resolution_m)
    return torch.where(distance_cells <= cell_radius, cost, torch.zeros_like(cost)).to(torch.uint8)


class Costmap(Slice2D):
    """Nav2-style costs on a grid (a ``Slice2D`` whose data are the costs): what a planner or
    ``nav_msgs/OccupancyGrid`` takes; ``slices.to_grid2d`` files it with its occupancy slice."""

    def __init__(self, cost: torch.Tensor, origin_xy_m: tuple[float, float], resolution_m: float):
        super().__init__(cost, origin_xy_m, resolution_m)

    @property
    def cost(self) -> torch.Tensor:
        """(H, W) uint8 Nav2 costs (0 free .. 252 decaying, 253 inscribed, 254 lethal, 255 unknown);
        rows = y, columns = x."""
        return self.data

    def occupancy_grid_data(self) -> np.ndarray:
        """(H * W,) int8 row-major ``nav_msgs/OccupancyGrid.data`` with Nav2's translation
        (``maps.cost_to_occupancy``)."""
        return cost_to_occupancy(self.cost.cpu().numpy()).reshape(-1)

    def occupancy_grid_info(self) -> dict:
        """``nav_msgs/MapMetaData`` fields: resolution, width, height, origin (corner, metres)."""
        return grid_info(self.origin_xy_m, self.resolution_m, self.shape)


def inflate(occupancy: Slice2D, cfg: InflationCfg | None = None) -> Costmap:
    """Nav2's inflation of an occupancy slice (``slices.occupancy_slice``: -1/0/1), its CPU torch ops on one
    thread (``torch_threads``)."""
    with one_torch_thread(occupancy.data.device):
        return _inflate(occupancy, cfg or InflationCfg())


def _inflate(occupancy: Slice2D, cfg: InflationCfg) -> Costmap:
    data = occupancy.data
    cell_radius = math.ceil(cfg.inflation_radius_m / occupancy.resolution_m)
    dist = edt(data == OCCUPIED, cell_radius)
    cost = nav2_cost(torch.where(torch.isfinite(dist), dist, torch.full_like(dist, 1e9)), occupancy.resolution_m, cfg)
    unknown = data == UNKNOWN
    threshold = 1 if cfg.inflate_unknown else INSCRIBED_INFLATED_OBSTACLE
    cost = torch.where(unknown & (cost < threshold), torch.full_like(cost, NO_INFORMATION), cost)
    return Costmap(cost=cost, origin_xy_m=occupancy.origin_xy_m, resolution_m=occupancy.resolution_m)


__all__ = ["FREE_SPACE", "HUMANOID_CIRCUMSCRIBED_RADIUS_M", "HUMANOID_FOOTPRINT_XY_M", "HUMANOID_INSCRIBED_RADIUS_M",
           "INSCRIBED_INFLATED_OBSTACLE", "LETHAL_OBSTACLE", "NO_INFORMATION", "Costmap", "InflationCfg", "inflate",
           "nav2_cost"]
