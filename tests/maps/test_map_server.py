"""ROS map_server maps: hand-written YAML + PGM fixtures load with Nav2's semantics (rows flipped,
negate, thresholds, unknown kept unknown and blocked for the planner); scale and raw modes follow
``nav2_map_server``'s formulas; written maps read back; bad input is one line naming the fix."""

from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from ambulo.cli import main
from ambulo.cli.plan import load_map
from ambulo.maps import Grid2D, load_map_image, load_map_yaml, save_map_yaml
from ambulo.maps.map_server import parse_flat_yaml, pixels_to_occupancy, read_image
from ambulo.utils.checks import InvalidValueError

DATA = Path(__file__).parent / "data"
ROOM = np.array([[-1, 0, 0, 0],  # row 0 = the image's bottom row (y 2.0-2.5 m)
                 [0, 0, 0, 100],
                 [100, 0, -1, 0]], np.int8)
"""``room.pgm`` as a Grid2D by hand: 0 -> 100, 254 -> 0, 205 -> -1, the top image row last."""


@pytest.mark.parametrize("name", ["room.yaml", "room_negate.yaml"])
def test_hand_written_map_loads_flipped_with_unknown_cells_unknown(name):
    grid = load_map_yaml(DATA / name)
    np.testing.assert_array_equal(grid.occupancy, ROOM)
    assert grid.origin_xy_m == (-1.0, 2.0) and grid.resolution_m == 0.5
    assert grid.cell_rect_xy_m(2, 0) == (-1.0, 3.0, -0.5, 3.5)  # the image's top-left pixel


@pytest.mark.parametrize("name", ["room.yaml", "room_negate.yaml"])
def test_the_planner_reads_a_map_server_yaml_with_unknown_cells_blocked(name):
    grid = load_map(str(DATA / name), 0.05, None)
    np.testing.assert_array_equal(grid.occupied, ROOM != 0)
    assert grid.origin_xy_m == (-1.0, 2.0) and grid.resolution_m == 0.5


def test_a_plan_cannot_start_on_unknown_ground(tmp_path, capsys):
    occupancy = np.zeros((60, 100), np.int8)  # 5 m x 3 m at 5 cm, all free but a never-seen strip
    occupancy[:, 40:60] = -1  # x = 2-3 m
    yaml = save_map_yaml(tmp_path / "seen.yaml", Grid2D(occupancy=occupancy, origin_xy_m=(0.0, 0.0),
                                                        resolution_m=0.05))
    assert main(["plan", "--map", str(yaml), "--start", "2.5,1.5,0", "--goal", "4,1.5",
                 "--png", str(tmp_path / "p.png")]) == 1
    assert "start_in_collision" in capsys.readouterr().out


def test_scale_and_raw_modes_follow_nav2():
    grey = np.array([[0, 40, 100, 128, 200, 230, 255]], np.uint8)
    occ = 1.0 - grey / 255.0
    scale = pixels_to_occupancy(grey, 255, mode="scale", negate=False, occupied_thresh=0.65, free_thresh=0.25)
    expected = np.where(occ > 0.65, 100, np.where(occ < 0.25, 0, np.rint((occ - 0.25) / 0.4 * 100)))
    assert scale.tolist() == expected.astype(int).tolist() == [[100, 100, 89, 62, 0, 0, 0]]
    rgba = np.stack([grey, grey, grey, np.array([[255, 255, 255, 0, 255, 255, 255]], np.uint8)], -1)
    assert pixels_to_occupancy(rgba, 255, mode="scale", negate=False, occupied_thresh=0.65,
                               free_thresh=0.25)[0, 3] == -1  # transparent -> unknown
    raw = pixels_to_occupancy(grey, 255, mode="raw", negate=True, occupied_thresh=0.65, free_thresh=0.25)
    assert raw.tolist() == [[0, 40, 100, -1, -1, -1, -1]]  # the pixel value itself, 0..100 only


def test_trinary_averages_alpha_in_as_nav2_does():
    la = np.array([[[0, 255], [0, 0]]], np.uint8)  # black opaque: occ 1 - 63.75 / 255 = 0.75; transparent: 1
    got = pixels_to_occupancy(la, 255, mode="trinary", negate=False, occupied_thresh=0.65, free_thresh=0.196)
    assert got.tolist() == [[100, 100]]
    la = np.array([[[200, 255], [200, 0]]], np.uint8)  # opaque: occ 1 - 213.75 / 255 = 0.16; transparent: 0.41
    got = pixels_to_occupancy(la, 255, mode="trinary", negate=False, occupied_thresh=0.65, free_thresh=0.196)
    assert got.tolist() == [[0, -1]]


@pytest.mark.parametrize("mode,fmt", [("trinary", "pgm"), ("trinary", "png"), ("raw", "pgm"), ("scale", "png")])
def test_written_maps_read_back(tmp_path, mode, fmt):
    occupancy = np.array([[-1, 0, 100], [100, 0, -1]], np.int8)
    grid = Grid2D(occupancy=occupancy, origin_xy_m=(0.125, -3.0), resolution_m=0.1)
    path = save_map_yaml(tmp_path / "m.yaml", grid, image_format=fmt, mode=mode)
    meta = parse_flat_yaml(path.read_text())
    assert meta["image"] == f"m.{fmt}" and meta["mode"] == mode and meta["origin"] == [0.125, -3.0, 0.0]
    back = load_map_yaml(path)
    np.testing.assert_array_equal(back.occupancy, occupancy)
    assert back.origin_xy_m == grid.origin_xy_m and back.resolution_m == grid.resolution_m
    if mode == "trinary":
        pixels, white = read_image(tmp_path / f"m.{fmt}")
        assert white == 255 and pixels.tolist() == [[0, 254, 205], [205, 254, 0]]  # map_saver's greys, top row first


def test_a_bare_image_is_read_as_map_server_reads_it(tmp_path):
    image = np.array([[0, 205], [254, 255]], np.uint8)
    iio.imwrite(tmp_path / "m.png", image)
    grid = load_map_image(tmp_path / "m.png", resolution_m=0.05)
    assert grid.occupancy.tolist() == [[0, 0], [100, -1]]


def write_yaml(tmp_path, text: str, image: bool = True) -> Path:
    if image:
        (tmp_path / "m.pgm").write_bytes(b"P5\n2 1\n255\n\x00\xfe")
    path = tmp_path / "m.yaml"
    path.write_text(text)
    return path


GOOD = "image: m.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"


@pytest.mark.parametrize("text,image,needle", [
    (GOOD, False, "map image"),
    (GOOD.replace("resolution: 0.05\n", ""), True, "m.yaml key 'resolution' is missing"),
    (GOOD.replace("0.196", "0.7"), True, "0 <= free_thresh < occupied_thresh <= 1"),
    (GOOD.replace("0.05", "-0.05"), True, "map resolution is -0.05"),
    (GOOD.replace("[0.0, 0.0, 0.0]", "[0.0, 0.0, 0.5]"), True, "origin yaw is 0.5: ambulo's 2-D maps are axis-aligned"),
    (GOOD + "mode: fancy\n", True, "map mode is 'fancy'"),
    (GOOD.replace("negate: 0", "negate: 2"), True, "'negate' is 2"),
])
def test_bad_map_yaml_is_one_line_with_a_fix(tmp_path, capsys, text, image, needle):
    path = write_yaml(tmp_path, text, image)
    assert main(["plan", "--map", str(path), "--png", str(tmp_path / "p.png")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ambulo plan: error: ") and needle in err[0], err
    assert ";" in err[0]  # the problem; then the fix


def test_bad_grids_are_refused_in_one_line():
    with pytest.raises(InvalidValueError, match="Grid2D.occupancy is a float64 array .* convert with"):
        Grid2D(occupancy=np.zeros((2, 2)), origin_xy_m=(0, 0), resolution_m=0.05)
    with pytest.raises(InvalidValueError, match="values must be -1"):
        Grid2D(occupancy=np.full((2, 2), 101, np.int8), origin_xy_m=(0, 0), resolution_m=0.05)
    with pytest.raises(InvalidValueError, match="scale maps are written as png"):
        save_map_yaml("x.yaml", Grid2D(occupancy=np.zeros((2, 2), np.int8), origin_xy_m=(0, 0), resolution_m=0.05),
                      mode="scale")


def test_origin_flag_is_refused_for_maps_that_carry_their_own(capsys, tmp_path):
    assert main(["plan", "--map", str(DATA / "room.yaml"), "--origin", "1,1", "--png", str(tmp_path / "p.png")]) == 2
    assert "room.yaml carries its own origin; drop --origin" in capsys.readouterr().err
