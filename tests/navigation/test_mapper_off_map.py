"""An estimated pose off the online map (the VO drifted past its 1 m margin) is no error: the
body disc marks the map's cells it covers and nothing else. Three of 200 full-mode benchmark
episodes stopped with ``ValueError: negative dimensions are not allowed`` from ``np.mgrid`` over the
disc's clamped, reversed cell range."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from ambulo.maps import Grid2D
from ambulo.navigation.mapping import OnlineMapper


@pytest.fixture
def mapper():
    """An online map over a 4 m x 3 m world (plus its 1 m margin: x -1..5, y -1..4)."""
    world = SimpleNamespace(occupancy=Grid2D(occupancy=np.zeros((60, 80), np.int8), origin_xy_m=(0.0, 0.0),
                                             resolution_m=0.05), start_pose=(1.0, 1.0, 0.0))
    m = OnlineMapper()
    m.reset(world)
    return m


@pytest.mark.parametrize("xy", [(9.0, 1.0), (-4.0, 1.0), (1.0, 7.5), (1.0, -3.0), (-6.0, -6.0), (40.0, 40.0)])
def test_a_pose_off_the_map_marks_nothing(mapper, xy):
    mapper.mark_body(np.array(xy))
    assert not mapper._body_free.any()
    assert not mapper.refresh(1.0, np.array(xy))


def test_a_pose_across_the_edge_marks_the_part_of_its_disc_on_the_map(mapper):
    """The disc (0.4 m) of a pose 0.2 m past the map's east edge: the cells within 0.4 m of it that
    the map has, no more."""
    x1 = mapper.grid.extent_xy_m()[2]
    xy = np.array([x1 + 0.2, 1.5])
    mapper.mark_body(xy)
    iy, ix = np.nonzero(mapper._body_free)
    cx, cy = mapper.grid.cell_center_xy_m(iy, ix)
    assert len(iy) and (np.hypot(cx - xy[0], cy - xy[1]) <= 0.4).all()
    assert (ix == mapper.grid.shape[1] - 1).any()  # it reaches the last column
    expected = sum(1 for kx in range(mapper.grid.shape[1]) for ky in range(mapper.grid.shape[0])
                   if math.hypot(*(np.array(mapper.grid.cell_center_xy_m(ky, kx)) - xy)) <= 0.4)
    assert len(iy) == expected


def test_a_felt_obstacle_is_occupied_even_where_the_robot_stood(mapper):
    """What the feet felt (the walker's ``felt_xy_m``) is an obstacle in the next map, over the
    body's free disc (the robot stood there before it tripped); off the map it is ignored."""
    from ambulo.maps import OCCUPIED

    xy = np.array([1.3, 1.2])
    mapper.mark_body(np.array([1.2, 1.2]))
    mapper.mark_obstacle(xy)
    mapper.mark_obstacle(np.array([40.0, 40.0]))
    assert mapper.refresh(1.0)
    iy, ix = mapper.grid.cell_of(xy)
    assert mapper.grid.occupancy[iy, ix] == OCCUPIED
    assert (mapper.grid.occupancy == OCCUPIED).sum() == 1
