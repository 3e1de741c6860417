"""The perception examples run headless and produce what they say."""

from pathlib import Path

from script_loader import run_main

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "perception"


def run_perception_example(file_name: str, *argv: str) -> dict:
    return run_main(EXAMPLES / file_name, *argv)


def test_rgbd_mapping_tracks_maps_and_draws_a_costmap(tmp_path):
    out = run_perception_example("rgbd_mapping.py", "--frames", "60", "--width", "320", "--height", "240",
                                 "--out", str(tmp_path))
    assert out["max_position_error_m"] < 0.05
    assert out["vertices"] > 1000
    cost = out["costmap"].cost
    assert (cost == 254).any() and (cost == 0).any()
    assert (tmp_path / "costmap.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "mesh.ply").read_bytes().startswith(b"ply\n")
