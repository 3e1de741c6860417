"""Nav2 inflation: every sampled cell equals Nav2's ``computeCost`` of its brute-force distance to
the nearest obstacle cell, unknown cells follow ``inflate_unknown``, and the OccupancyGrid
translation matches Nav2's publisher."""

import math

import numpy as np
import pytest
import torch

from ambulo.perception.costmap import InflationCfg, inflate
from ambulo.perception.slices import OCCUPIED, UNKNOWN, Slice2D


def nav2_compute_cost(distance_cells: float, resolution: float, inscribed: float, scaling: float) -> int:
    """``nav2_costmap_2d::InflationLayer::computeCost``, transcribed line by line."""
    if distance_cells == 0:
        return 254  # LETHAL_OBSTACLE
    if distance_cells * resolution <= inscribed:
        return 253  # INSCRIBED_INFLATED_OBSTACLE
    factor = math.exp(-1.0 * scaling * (distance_cells * resolution - inscribed))
    return int((253 - 1) * factor)  # static_cast<unsigned char> truncates


def random_occupancy(seed=0, shape=(60, 80)):
    rng = np.random.default_rng(seed)
    data = np.zeros(shape, np.int8)
    for _ in range(6):
        y, x = rng.integers(0, shape[0]), rng.integers(0, shape[1])
        data[y:y + rng.integers(1, 6), x:x + rng.integers(1, 9)] = OCCUPIED
    data[:5, 60:] = UNKNOWN
    return data


@pytest.mark.parametrize("cfg", [InflationCfg(), InflationCfg(inflation_radius_m=1.0, cost_scaling_factor=3.0,
                                                                 inscribed_radius_m=0.3)])
def test_inflation_equals_nav2_formula_at_sampled_cells(cfg):
    resolution = 0.05
    data = random_occupancy()
    costmap = inflate(Slice2D(torch.from_numpy(data), (1.0, -2.0), resolution), cfg).cost.numpy()
    assert costmap.dtype == np.uint8 and costmap.shape == data.shape
    obstacles = np.argwhere(data == OCCUPIED)
    cell_radius = math.ceil(cfg.inflation_radius_m / resolution)  # Nav2's cell_inflation_radius_
    rng = np.random.default_rng(1)
    for iy, ix in rng.integers(0, data.shape, (400, 2)):
        d = np.sqrt(((obstacles - (iy, ix)) ** 2).sum(1)).min()
        expected = nav2_compute_cost(d, resolution, cfg.inscribed_radius_m, cfg.cost_scaling_factor) \
            if d <= cell_radius else 0
        if data[iy, ix] == UNKNOWN and expected < 253:
            expected = 255  # NO_INFORMATION stays unless inflated to at least inscribed
        assert costmap[iy, ix] == expected, (iy, ix, d)


def test_cost_profile_along_a_line_from_a_wall():
    data = np.zeros((1, 40), np.int8)
    data[0, 0] = OCCUPIED
    cfg = InflationCfg(inflation_radius_m=1.0, cost_scaling_factor=5.0, inscribed_radius_m=0.2)
    cost = inflate(Slice2D(torch.from_numpy(data), (0, 0), 0.05), cfg).cost[0].tolist()
    assert cost[0] == 254 and cost[1:5] == [253] * 4  # 0.05 .. 0.20 m: inscribed
    assert cost[5] == int(252 * math.exp(-5.0 * 0.05))
    assert cost[20] == int(252 * math.exp(-5.0 * 0.8)) and cost[21] == 0  # radius 1 m = 20 cells
    assert all(a >= b for a, b in zip(cost[4:], cost[5:]))


def test_occupancy_grid_data_uses_nav2s_translation_table():
    from ambulo.perception.costmap import Costmap

    cost = torch.tensor([[0, 1, 100, 252, 253, 254, 255]], dtype=torch.uint8)
    grid = Costmap(cost, (0.45, 0.45), 0.1)  # origin_xy_m is the lower-left corner of cell [0, 0], as ROS's
    assert grid.occupancy_grid_data().tolist() == [0, 1, 1 + 97 * 99 // 251, 1 + 97 * 251 // 251, 99, 100, -1]
    info = grid.occupancy_grid_info()
    assert info["origin"]["position"]["x"] == pytest.approx(0.45) and (info["width"], info["height"]) == (7, 1)
