"""The perception examples run headless and produce what they say."""

import importlib.util
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "perception"


def run_perception_example(file_name: str, *argv: str) -> dict:
    spec = importlib.util.spec_from_file_location(f"perception_example_{Path(file_name).stem}", EXAMPLES / file_name)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main(list(argv))


def test_rgbd_mapping_tracks_maps_and_draws_a_costmap(tmp_path):
    out = run_perception_example("rgbd_mapping.py", "--frames", "60", "--width", "320", "--height", "240",
                                 "--out", str(tmp_path))
    assert out["max_position_error_m"] < 0.05
    assert out["vertices"] > 1000
    cost = out["costmap"].cost
    assert (cost == 254).any() and (cost == 0).any()
    assert (tmp_path / "costmap.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "mesh.ply").read_bytes().startswith(b"ply\n")
