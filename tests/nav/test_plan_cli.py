"""``ambulo plan``: footsteps on a map to a PNG, and with --simulate the humanoid walking them (MP4)."""

import numpy as np
import pytest

from ambulo.cli import build_parser, main

pytest.importorskip("matplotlib")

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_plan_is_a_registered_command():
    assert "plan" in build_parser()._subparsers._group_actions[0].choices


def test_plan_draws_the_footsteps_on_the_map(tmp_path, capsys):
    png = tmp_path / "plan.png"
    assert main(["plan", "--map", "boxes", "--goal", "3.5,0,0", "--png", str(png)]) == 0
    out = capsys.readouterr().out
    assert "plan: success" in out and str(png) in out
    assert png.read_bytes()[:8] == PNG_MAGIC


def test_plan_reads_an_occupancy_file_and_reports_a_blocked_start(tmp_path, capsys):
    occupied = np.zeros((60, 100), bool)  # 5 m x 3 m at 5 cm
    occupied[:, 40:44] = True  # a wall across the room at x = 2.0-2.2 m
    path = tmp_path / "room.npy"
    np.save(path, occupied)
    png = tmp_path / "blocked.png"
    status = main(["plan", "--map", str(path), "--start", "2.1,1.5,0", "--goal", "4,1.5", "--png", str(png)])
    assert status == 1
    assert "start_in_collision" in capsys.readouterr().out
    assert png.read_bytes()[:8] == PNG_MAGIC


@pytest.mark.parametrize("argv, needle", [
    (["--start", "1,x"], "--start '1,x' is not a pose"),
    (["--map", "nowhere.npy"], "neither a file nor a built-in map"),
    (["--resolution", "0"], "--resolution 0.0 is not a positive cell size"),
])
def test_bad_plan_input_is_one_line(argv, needle, capsys, tmp_path):
    assert main(["plan", "--png", str(tmp_path / "p.png"), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ambulo plan: error: ") and needle in err[0]


def test_plan_simulate_walks_the_humanoid_and_writes_a_video(tmp_path, capsys):
    png, video = tmp_path / "walk.png", tmp_path / "walk.mp4"
    status = main(["plan", "--goal", "1.03,0,0", "--png", str(png), "--simulate", "--video", str(video),
                   "--seed", "2"])
    out = capsys.readouterr().out
    assert status == 0, out
    assert "walk: no fall" in out and "100.0 % of single-support samples" in out
    assert png.read_bytes()[:8] == PNG_MAGIC
    assert video.stat().st_size > 10_000


def test_plan_reads_an_image_map_with_dark_obstacles(tmp_path, capsys):
    import imageio.v2 as imageio

    image = np.full((80, 120), 255, np.uint8)  # 6 m x 4 m at 5 cm; the top row is the far (high) y
    image[10:20, 50:60] = 0  # a block at x = 2.5-3.0 m, y = 3.0-3.5 m, right between start and goal
    path = tmp_path / "room.png"
    imageio.imwrite(path, image)
    from ambulo.cli.plan import load_map

    grid = load_map(str(path), 0.05, None)
    assert grid.occupied.sum() == 100 and grid.occupied[60:70, 50:60].all()
    png = tmp_path / "around.png"
    assert main(["plan", "--map", str(path), "--start", "1,3.25,0", "--goal", "5,3.25,0", "--png", str(png)]) == 0
    assert "plan: success" in capsys.readouterr().out
