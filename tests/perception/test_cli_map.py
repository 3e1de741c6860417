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
    (["map", "indoor", "--voxel", "5"], "--voxel 5.0 m is outside"),
])
def test_bad_input_is_one_line(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and message in err and err.startswith("ambulo map: error:")
