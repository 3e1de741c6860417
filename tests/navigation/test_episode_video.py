"""The episode video and final map: drawn layers land where the world says (pixel positions worked
out by hand from the map's corner and scale), the MP4 reads back with its frame count and size."""

import math

import imageio.v2 as imageio
import imageio.v3 as iio
import numpy as np
import pytest
import torch

from ambulo.maps import Grid2D
from ambulo.nav import FootstepPlan, PlanStatus
from ambulo.navigation.localization import PoseEstimate
from ambulo.navigation.navigator import NavSnapshot
from ambulo.navigation.topdown import COLORS, TopDown, crop, polyline_points, rect_points
from ambulo.navigation.video import EpisodeVideo, VideoCfg
from ambulo.perception.frames import RgbdFrame

RES_M = 0.05
ORIGIN = (-1.0, -0.5)


def _grid() -> Grid2D:
    """A 4 m x 2 m map (80 x 40 cells): a wall across x = 2.0..2.1 m below y = 0.5 m, the top
    strip y > 1.2 m unknown."""
    occ = np.zeros((40, 80), np.int8)
    occ[:20, 60:62] = 100  # x = 2.0..2.1 m, y = -0.5..0.5 m
    occ[34:, :] = -1  # y >= 1.2 m
    return Grid2D(occupancy=occ, origin_xy_m=ORIGIN, resolution_m=RES_M)


def _plan() -> FootstepPlan:
    feet = np.array([[0.0, 0.1, 0.0], [0.0, -0.1, 0.0], [0.5, 0.1, 0.0], [1.0, -0.1, math.pi / 2]])
    return FootstepPlan(PlanStatus.SUCCESS, feet, np.array([1, -1, 1, -1], np.int8), np.zeros(4), 0.0, 0, 0.0)


def _snapshot(k: int, grid: Grid2D) -> NavSnapshot:
    """The robot walking along y = 0 at 0.1 m per frame, its estimate 0.2 m to the left (y + 0.2)."""
    x = 0.1 * k
    walked = np.stack([0.1 * np.arange(k + 1), np.zeros(k + 1)], -1)
    rgb = np.zeros((60, 80, 3), np.uint8)
    rgb[..., 0] = 20 * k  # a frame that changes
    frame = RgbdFrame(depth_m=torch.ones(60, 80), rgb=torch.from_numpy(rgb), intrinsics=torch.eye(3, dtype=torch.float64))
    return NavSnapshot(time_s=0.1 * k, true_pose=np.array([x, 0.0, 0.0]),
                       estimate=PoseEstimate(np.array([x, 0.2, 0.0]), True, 0.1 * k), frame=frame,
                       goal_xy_m=np.array([2.5, 1.0]), route_xy_m=np.array([[x, 0.0], [2.5, 1.0]]), footsteps=_plan(),
                       occupancy=grid, walked_xy_m=walked, command=None, status="walking")


def _pixel(xy, s: float, height: int) -> tuple[int, int]:
    """By hand: column (x - ox) s, row H - (y - oy) s."""
    return int(height - (xy[1] - ORIGIN[1]) * s), int((xy[0] - ORIGIN[0]) * s)


def test_map_png_has_each_layer_where_the_world_puts_it(tmp_path):
    grid = _grid()
    video = EpisodeVideo(None, VideoCfg(map_png_px_per_m=100.0), map_png=tmp_path / "map.png")
    for k in range(6):
        video(_snapshot(k, grid))
    written = video.close(final_pose_xyyaw=(0.6, 0.0, 0.0))
    assert written == [tmp_path / "map.png"]
    png = iio.imread(tmp_path / "map.png")
    s = 100.0
    assert png.shape == (200, 400, 3)  # 2 m x 4 m at 100 px/m
    h = png.shape[0]
    # the true path: y = 0 from x = 0 to 0.6 (the robot's disc covers its end)
    for x in (0.05, 0.15, 0.25):
        assert tuple(png[_pixel((x, 0.0), s, h)]) == COLORS["true"], x
    # the estimated path 0.2 m to the left of it
    for x in (0.05, 0.25):
        assert tuple(png[_pixel((x, 0.2), s, h)]) == COLORS["estimated"], x
    # the wall black, the unknown strip grey, open floor white, the floor next to the wall tinted
    assert tuple(png[_pixel((2.05, 0.0), s, h)]) == COLORS["occupied"]
    assert tuple(png[_pixel((0.0, 1.4), s, h)]) == COLORS["unknown"]
    assert tuple(png[_pixel((-0.5, -0.3), s, h)]) == COLORS["free"]
    assert tuple(png[_pixel((1.9, -0.3), s, h)]) == COLORS["inflated"]  # 0.1 m from the wall
    # the robot at its final pose, the goal's centre
    assert tuple(png[_pixel((0.6, -0.08), s, h)]) == COLORS["robot"]  # beside its white heading line
    assert tuple(png[_pixel((2.5, 1.0), s, h)]) == COLORS["goal"]
    # the last foot (right, yawed 90 deg) at (1.0, -0.1): its border is 0.11 m along y from its
    # centre (the sole's length runs along y now) and 0.05 m along x
    fill = png[_pixel((1.0, -0.1), s, h)]
    assert fill[0] > fill[1] and fill[0] > fill[2]  # a light red inside
    assert tuple(png[_pixel((1.0, -0.1 + 0.105), s, h)]) == COLORS["right"]
    assert tuple(png[_pixel((1.0 + 0.07, -0.1), s, h)]) == COLORS["free"]  # outside the sole
    # the left foot at (0.5, 0.1), yaw 0: its heel border 0.105 m back along x
    assert tuple(png[_pixel((0.5 - 0.105, 0.1), s, h)]) == COLORS["left"]


def test_the_video_reads_back_frame_for_frame(tmp_path):
    grid = _grid()
    cfg = VideoCfg(panel_height_px=120, map_max_width_px=240, caption_height_px=16)
    video = EpisodeVideo(tmp_path / "ep.mp4", cfg, map_png=tmp_path / "map.png", title="test")
    for k in range(7):
        video(_snapshot(k, grid))
    files = video.close()
    assert (tmp_path / "ep.mp4") in files and (tmp_path / "map.png") in files
    reader = imageio.get_reader(tmp_path / "ep.mp4")
    assert reader.count_frames() == 7
    frames = [reader.get_data(i) for i in (0, 3, 6)]
    # camera 80x60 scaled to 160x120, map 4 m x 2 m at min(120/2, 240/4) = 60 px/m -> 240 x 120;
    # height 120 + 16 caption = 136 (a multiple of 8), width 400
    assert frames[0].shape == (136, 400, 3)
    assert video.last_frame.shape == (136, 400, 3)
    # the camera panel carries each frame's red level (lossy: within a few levels)
    assert abs(int(frames[1][60, 80, 0]) - 60) < 12 and abs(int(frames[2][60, 80, 0]) - 120) < 12


def test_every_n_frames_films_a_subset(tmp_path):
    grid = _grid()
    video = EpisodeVideo(tmp_path / "ep.mp4", VideoCfg(every_n_frames=3, panel_height_px=64, map_max_width_px=128))
    for k in range(7):  # frames 0, 3, 6
        video(_snapshot(k, grid))
    video.close()
    assert video.frames_written == 3
    assert imageio.get_reader(tmp_path / "ep.mp4").count_frames() == 3
    assert len(video.true_xy_m) == 7  # the paths keep every frame


def test_polyline_and_rect_sampling_by_hand():
    pts = polyline_points(np.array([[0.0, 0.0], [0.0, 2.0], [2.0, 2.0]]), spacing_px=0.5)
    assert len(pts) == 4 + 4 + 1 and np.allclose(pts[-1], (2.0, 2.0))
    assert np.abs(np.diff(pts, axis=0)).sum(axis=1).max() == pytest.approx(0.5)
    # a 10 x 4 px rectangle yawed 90 deg: long along the rows (world +x -> +column becomes world
    # +y -> -row)
    border, inside = rect_points(np.array([[50.0, 50.0]]), np.array([math.pi / 2]), (5.0, 2.0))
    allp = np.concatenate([border, inside])
    assert np.ptp(allp[:, 0]) == pytest.approx(10.0) and np.ptp(allp[:, 1]) == pytest.approx(4.0)
    # yawed 45 deg: the toe points up-right in the picture (row -, column +), the sole's side down-right
    border, inside = rect_points(np.array([[50.0, 50.0]]), np.array([math.pi / 4]), (5.0, 2.0))
    rel = np.concatenate([border, inside]) - 50.0
    along, across = np.array([-1.0, 1.0]) / math.sqrt(2), np.array([1.0, 1.0]) / math.sqrt(2)
    assert (rel @ along).max() == pytest.approx(5.0) and np.abs(rel @ across).max() == pytest.approx(2.0)


def test_a_view_crops_the_map_on_its_lattice_and_pads_with_unknown():
    grid = _grid()  # x -1..3, y -0.5..1.5 m
    view = crop(grid, (1.5, -1.0, 2.52, 0.0))  # past the bottom edge; 2.52 grows to the cell edge 2.55
    assert view.origin_xy_m == pytest.approx((1.5, -1.0)) and view.shape == (20, 21)
    assert (view.occupancy[:10] == -1).all()  # y -1.0..-0.5: outside the map
    assert (view.occupancy[10:, 10:12] == 100).all() and (view.occupancy[10:, :10] == 0).all()  # the wall at x 2.0
    # drawn through a view, a world point lands on the same map content as without one
    td, full = TopDown(20.0, (1.5, -1.0, 2.52, 0.0)), TopDown(20.0)
    for xy in ((2.05, -0.2), (1.7, -0.2)):
        a, b = td.pixel_of(grid, xy)[0].astype(int), full.pixel_of(grid, xy)[0].astype(int)
        assert tuple(td.base(grid)[a[0], a[1]]) == tuple(full.base(grid)[b[0], b[1]])


def test_the_map_picture_is_rebuilt_only_for_a_new_grid():
    grid = _grid()
    td = TopDown(20.0)
    assert td.base(grid) is td.base(grid)
    other = Grid2D(occupancy=grid.occupancy.copy(), origin_xy_m=ORIGIN, resolution_m=RES_M)
    assert td.base(other) is not td.base(grid)


@pytest.mark.slow
def test_a_real_oracle_episode_films_every_frame_and_draws_where_the_robot_went(tmp_path):
    from ambulo.navigation import EpisodeCfg, run_episode

    video = EpisodeVideo(tmp_path / "ep.mp4", VideoCfg(panel_height_px=240, map_max_width_px=400),
                         map_png=tmp_path / "map.png")
    result = run_episode(1000, 0, EpisodeCfg(min_geodesic_m=3.0, max_geodesic_m=3.5), observer=video)
    video.close()
    assert result.frames == video.frames_written
    reader = imageio.get_reader(tmp_path / "ep.mp4")
    assert reader.count_frames() == result.frames
    assert tuple(reader.get_meta_data()["size"]) == video.last_frame.shape[1::-1]
    png = iio.imread(tmp_path / "map.png")
    img, topdown = video.final_map()
    assert np.array_equal(png, img)
    true = np.array(video.true_xy_m)
    far = np.linalg.norm(true - true[-1], axis=1) > 0.3  # the robot's disc covers the path's end
    rc = topdown.pixel_of(video.last.occupancy, true[far]).astype(int)
    on_path = np.all(png[rc[:, 0], rc[:, 1]] == COLORS["true"], axis=-1)
    assert on_path.mean() > 0.95  # a few points may sit under the goal mark
