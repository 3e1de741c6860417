"""One cell's world rectangle is the same, to the last bit, through every loader and writer of a 2-D
map: perception's slice -> ``maps.Grid2D`` -> .npz, map_server YAML + PGM/PNG, OccupancyGrid (dict
and message) -> the footstep planner's ``GridMap``; and it equals the corners computed by hand."""

import numpy as np
import pytest
import torch

from ambulo.maps import (
    OCCUPIED,
    Grid2D,
    from_occupancy_grid,
    load_map_yaml,
    load_npz,
    save_map_yaml,
    save_npz,
    to_msg,
    to_occupancy_grid,
)
from ambulo.nav import GridMap
from ambulo.perception.costmap import inflate
from ambulo.perception.slices import occupancy_slice, to_grid2d
from ambulo.perception.tsdf import DenseGrid

VOXEL_M = 0.05
ORIGIN_INDEX = (-20, 40, 0)
"""World voxel index of the dense grid's voxel [0, 0, 0]: its centre is at (-1.0, 2.0, 0.0) m."""
CELL = (3, 7)
"""(iy, ix): the one occupied cell, over voxel column x index -20 + 7 = -13, y index 40 + 3 = 43."""
HAND_RECT = (-0.675, 2.125, -0.625, 2.175)
"""Cell [3, 7] by hand: voxel column centre (-13 * 0.05, 43 * 0.05) = (-0.65, 2.15) m, +- half a voxel."""


def perception_map() -> Grid2D:
    """What ``ambulo map`` files: an occupancy slice of a dense TSDF grid and its costmap."""
    nx, ny, nz = 12, 6, 8
    tsdf = torch.ones(nx, ny, nz)
    tsdf[CELL[1], CELL[0], 2:6] = -0.5  # a post in the height band: behind a surface
    grid = DenseGrid(tsdf=tsdf, weight=torch.ones(nx, ny, nz), color=torch.zeros(nx, ny, nz, 3, dtype=torch.uint8),
                     origin_index=torch.tensor(ORIGIN_INDEX), voxel_size_m=VOXEL_M, truncation_m=0.15)
    occupancy = occupancy_slice(grid, 0.05, 0.35)
    assert occupancy.cell_rect_xy_m(*CELL) == pytest.approx(HAND_RECT, abs=1e-12)
    assert occupancy.cell_of((-0.65, 2.15)) == CELL  # the voxel column's centre is the cell's centre
    return to_grid2d(occupancy, inflate(occupancy))


def occupied_cell_rect(grid) -> tuple[float, ...]:
    cells = np.argwhere(grid.occupied() if isinstance(grid, Grid2D) else grid.occupied)
    assert cells.tolist() == [list(CELL)]
    return grid.cell_rect_xy_m(*cells[0])


def test_one_cells_rectangle_is_identical_through_every_loader_and_writer(tmp_path):
    grid = perception_map()
    assert grid.cost is not None and grid.cost[CELL] == 254 and grid.occupancy[CELL] == OCCUPIED
    rect = occupied_cell_rect(grid)
    assert rect == pytest.approx(HAND_RECT, abs=1e-12)
    through = {
        "npz": load_npz(save_npz(tmp_path / "m.npz", grid)),
        "yaml+pgm": load_map_yaml(save_map_yaml(tmp_path / "m.yaml", grid)),
        "yaml+png": load_map_yaml(save_map_yaml(tmp_path / "p.yaml", grid, image_format="png")),
        "OccupancyGrid dict": from_occupancy_grid(to_occupancy_grid(grid)),
    }
    try:  # the message as it arrives (float32 resolution), when the ros2 extra is installed
        from nav_msgs.msg import OccupancyGrid
        from rclpy.serialization import deserialize_message, serialize_message

        wire = serialize_message(to_msg(to_occupancy_grid(grid)))
        through["OccupancyGrid msg"] = from_occupancy_grid(deserialize_message(wire, OccupancyGrid))
    except ModuleNotFoundError:  # no ros2 extra: the dict form above has the message's fields
        pass
    through["planner GridMap"] = GridMap.from_map(through["npz"])
    for name, loaded in through.items():
        assert occupied_cell_rect(loaded) == rect, name
        assert loaded.shape == grid.shape and loaded.extent_xy_m() == grid.extent_xy_m(), name


def test_cell_arithmetic_by_hand():
    grid = Grid2D(occupancy=np.zeros((4, 5), np.int8), origin_xy_m=(-1.0, 2.0), resolution_m=0.5)
    assert grid.cell_rect_xy_m(1, 2) == (0.0, 2.5, 0.5, 3.0)
    assert tuple(map(float, grid.cell_center_xy_m(1, 2))) == (0.25, 2.75)
    assert grid.cell_of((0.0, 2.5)) == (1, 2) and grid.cell_of((-0.01, 2.49)) == (0, 1)  # borders go up/right
    assert grid.cell_of((-1.01, 2.0)) == (0, -1)  # off the map: the caller checks bounds
    iy, ix = grid.cells_of(np.array([[0.25, 2.75], [1.49, 3.99]]))
    assert iy.tolist() == [1, 3] and ix.tolist() == [2, 4]
    assert grid.extent_xy_m() == (-1.0, 2.0, 1.5, 4.0)
    centres = grid.cell_centers_xy_m()
    assert centres.shape == (4, 5, 2) and tuple(centres[1, 2]) == (0.25, 2.75)
