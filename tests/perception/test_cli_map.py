"""``ambulo map``: writes what it says, and bad input is one line."""

import json

import numpy as np
import pytest

from ambulo.cli import main


def test_map_writes_trajectory_mesh_and_pictures(tmp_path, capsys):
    out = tmp_path / "map"
    assert main(["map", "indoor", "--frames", "30", "--width", "160", "--height", "120", "--out", str(out)]) == 0
    for name in ("estimate.tum", "groundtruth.tum", "mesh.ply", "occupancy.png", "costmap.png", "steppable.png",
                 "costmap.npz", "summary.json"):
        assert (out / name).stat().st_size > 0, name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["trajectory"]["num_poses"] == 30
    assert summary["trajectory"]["ate_rmse_m"] < 0.05
    assert summary["occupancy_cells"]["occupied"] > 0
    lines = (out / "estimate.tum").read_text().splitlines()
    assert len(lines) == 31 and len(lines[1].split()) == 8
    cost = np.load(out / "costmap.npz")["cost"]
    assert cost.dtype == np.uint8 and {254, 253} <= set(np.unique(cost).tolist())
    assert "ATE" in capsys.readouterr().out


@pytest.mark.parametrize("argv,message", [
    (["map", "kitchen"], "no scene named 'kitchen'"),
    (["map", "indoor", "--frames", "1"], "--frames 1 is too small"),
    (["map", "indoor", "--frames", "0"], "--frames 0 is too small; give --frames of at least 2"),
    (["map", "indoor", "--frames", "-3"], "--frames -3 is too small; give --frames of at least 2"),
    (["map", "indoor", "--voxel", "5"], "--voxel 5.0 m is outside"),
])
def test_bad_input_is_one_line(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and message in err and err.startswith("ambulo map: error:")


@pytest.mark.parametrize("size,frames,reason", [
    (("160", "120"), 2, "2 poses: the alignment needs at least 3 poses not on one line"),
])
def test_a_run_too_short_or_still_to_score_still_maps(tmp_path, capsys, size, frames, reason):
    """evo's Umeyama alignment raised on these (a degenerate covariance): the map is still written and
    the score says why it is missing."""
    out = tmp_path / "map"
    argv = ["map", "indoor", "--frames", str(frames), "--width", size[0], "--height", size[1], "--out", str(out)]
    assert main(argv) == 0
    for name in ("estimate.tum", "groundtruth.tum", "mesh.ply", "costmap.png", "costmap.npz", "summary.json"):
        assert (out / name).stat().st_size > 0, name
    t = json.loads((out / "summary.json").read_text())["trajectory"]
    assert t["num_poses"] == frames and t["ate_rmse_m"] is None and reason in t["ate_unavailable"]
    assert t["rpe_percent"] is None and "no pose pairs 1 m apart" in t["rpe_unavailable"]
    printed = capsys.readouterr().out
    assert "trajectory: ATE n/a, RPE n/a" in printed and f"ATE not available: {reason}" in printed
    assert "visual odometry never started" not in printed


def test_an_odometry_that_never_tracks_fuses_nothing_and_says_so(tmp_path, capsys):
    """Too few features at 64x48: the odometry never starts, so no pose may be fused (the map was
    once fused at the start pose while the camera walked on): one line naming the fix."""
    argv = ["map", "indoor", "--frames", "3", "--width", "64", "--height", "48", "--out", str(tmp_path / "map")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "tracked none of the 3 frames" in err and "--true-poses" in err
