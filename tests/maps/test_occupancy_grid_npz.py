"""``nav_msgs/OccupancyGrid`` (dict form and the real message) and ambulo's ``.npz``: layout, the
float32 resolution, the cost layer's Nav2 translation, and refusals in one line."""

import math

import numpy as np
import pytest

from ambulo.maps import Grid2D, from_occupancy_grid, load_npz, save_npz, to_msg, to_occupancy_grid
from ambulo.maps.npz import FORMAT, VERSION
from ambulo.utils.checks import InvalidValueError

OCCUPANCY = np.array([[0, 100, -1], [37, 0, 0]], np.int8)
COST = np.array([[0, 254, 255], [253, 1, 252]], np.uint8)


def grid() -> Grid2D:
    return Grid2D(occupancy=OCCUPANCY, origin_xy_m=(-1.025, 2.475), resolution_m=0.05, cost=COST)


def test_occupancy_grid_is_row_major_from_the_origin_with_the_corner_as_origin():
    msg = to_occupancy_grid(grid(), frame_id="odom")
    assert msg["header"] == {"frame_id": "odom"}
    assert msg["info"] == {"resolution": 0.05, "width": 3, "height": 2,
                           "origin": {"position": {"x": -1.025, "y": 2.475, "z": 0.0},
                                      "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}}
    assert msg["data"].dtype == np.int8 and msg["data"].tolist() == [0, 100, -1, 37, 0, 0]  # data[iy * W + ix]
    costs = to_occupancy_grid(grid(), layer="cost")["data"].tolist()
    assert costs == [0, 100, -1, 99, 1, 1 + 97 * 251 // 251]  # Nav2's Costmap2DPublisher table


def test_the_real_message_round_trips_despite_its_float32_resolution():
    pytest.importorskip("nav_msgs")
    serialization = pytest.importorskip("rclpy.serialization")
    from nav_msgs.msg import OccupancyGrid

    msg = to_msg(to_occupancy_grid(grid()))
    assert isinstance(msg, OccupancyGrid)
    msg = serialization.deserialize_message(serialization.serialize_message(msg), OccupancyGrid)  # over the wire
    assert msg.info.resolution == float(np.float32(0.05)) != 0.05  # float32 0.0500000007...
    back = from_occupancy_grid(msg)
    assert back.resolution_m == 0.05 and back.origin_xy_m == (-1.025, 2.475) and back.cost is None
    np.testing.assert_array_equal(back.occupancy, OCCUPANCY)


@pytest.mark.parametrize("orientation,needle", [
    ({"x": 0.0, "y": 0.0, "z": math.sin(0.25), "w": math.cos(0.25)}, "yaw is 0.5"),
    ({"x": 0.1, "y": 0.0, "z": 0.0, "w": 0.995}, "the map is tilted"),
])
def test_a_rotated_occupancy_grid_is_refused(orientation, needle):
    msg = to_occupancy_grid(grid())
    msg["info"]["origin"]["orientation"] = orientation
    with pytest.raises(InvalidValueError, match=needle):
        from_occupancy_grid(msg)


def test_a_half_turn_quaternion_with_negative_w_is_still_no_rotation():
    msg = to_occupancy_grid(grid())
    msg["info"]["origin"]["orientation"] = {"x": 0.0, "y": 0.0, "z": 0.0, "w": -1.0}
    assert from_occupancy_grid(msg).origin_xy_m == (-1.025, 2.475)


def test_bad_occupancy_grids_are_refused():
    msg = to_occupancy_grid(grid())
    msg["data"] = msg["data"][:-1]
    with pytest.raises(InvalidValueError, match="info says 3 x 2 = 6"):
        from_occupancy_grid(msg)
    with pytest.raises(InvalidValueError, match="OccupancyGrid field 'info' is missing"):
        from_occupancy_grid({"data": []})


def test_npz_keeps_everything_and_says_what_it_is(tmp_path):
    path = save_npz(tmp_path / "sub" / "m.npz", grid())
    with np.load(path) as raw:  # readable without ambulo
        assert str(raw["format"]) == FORMAT and int(raw["version"]) == VERSION
        assert raw["origin_xy_m"].tolist() == [-1.025, 2.475] and raw["cost"].dtype == np.uint8
    back = load_npz(path)
    np.testing.assert_array_equal(back.occupancy, OCCUPANCY)
    np.testing.assert_array_equal(back.cost, COST)
    assert back.origin_xy_m == (-1.025, 2.475) and back.resolution_m == 0.05
    no_cost = load_npz(save_npz(tmp_path / "n.npz", Grid2D(occupancy=OCCUPANCY, origin_xy_m=(0, 0), resolution_m=1)))
    assert no_cost.cost is None


def test_old_and_foreign_npz_files_are_refused_with_a_fix(tmp_path):
    old = tmp_path / "costmap.npz"  # what ambulo map wrote before: origin_xy_m was a cell centre
    np.savez_compressed(old, cost=COST, origin_xy_m=np.array([-1.0, 2.5]), resolution_m=0.05)
    with pytest.raises(InvalidValueError, match="before the maps format .*re-run ambulo map"):
        load_npz(old)
    newer = tmp_path / "newer.npz"
    np.savez(newer, format=np.array(FORMAT), version=np.array(VERSION + 1), occupancy=OCCUPANCY)
    with pytest.raises(InvalidValueError, match="this ambulo reads version 1"):
        load_npz(newer)
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(InvalidValueError, match="not a .npz archive"):
        load_npz(tmp_path / "junk.npz")
    with pytest.raises(FileNotFoundError, match="no map file"):
        load_npz(tmp_path / "missing.npz")
