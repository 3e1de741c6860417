"""Every example (an Isaac tutorial ported) runs headless and does what it says."""

import ast
import functools
import math
from pathlib import Path

import numpy as np
import pytest

from script_loader import run_main

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run_example(name: str, *argv: str) -> dict:
    return run_main(EXAMPLES / f"{name}.py", *argv)


@functools.cache
def _examples_loaded_by_tests() -> frozenset[str]:
    """Names of the examples some test module loads: ``run_example("name", ...)``, or a path
    ``... "examples" / "name.py"`` (string constants "examples" and "name.py" in one module)."""
    loaded = set()
    for file in Path(__file__).resolve().parent.rglob("test_*.py"):
        strings = set()
        for node in ast.walk(ast.parse(file.read_text(), str(file))):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "run_example"
                    and node.args and isinstance(node.args[0], ast.Constant)):
                loaded.add(node.args[0].value)
            elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                strings.add(node.value)
        if "examples" in strings:
            loaded |= {s[:-3] for s in strings if s.endswith(".py") and s[:-3].isidentifier()}
    return frozenset(loaded)


@pytest.mark.parametrize("example", sorted(p.stem for p in EXAMPLES.glob("*.py")))
def test_every_example_has_a_test(example):
    assert example in _examples_loaded_by_tests(), (
        f"examples/{example}.py is run by no test: add one to tests/test_examples.py "
        f"(run_example({example!r}, ...)) or to its package's test module"
    )


def test_hello_world_cube_lands_at_half_its_edge(tmp_path):
    out = run_example("hello_world", "--steps", "400", "--video", str(tmp_path / "hw.mp4"))
    assert out["final_position"][2] == pytest.approx(0.5015 / 2, abs=0.002)
    assert (tmp_path / "hw.mp4").stat().st_size > 1000


def test_hello_robot_drives_with_random_wheel_velocities():
    out = run_example("hello_robot", "--steps", "120")  # 2 s at Isaac's 1/60 s per step
    # mean wheel speed 2.5 rad/s * 0.03 m = 0.075 m/s for 2 s: ~0.15 m, less when turning
    for key in ("callback_distance", "wheeled_distance"):
        assert 0.05 < out[key] < 0.2


def test_simple_wheeled_robot_drives_then_turns():
    out = run_example("simple_wheeled_robot", "--seconds", "4")
    assert out["position"][0] == pytest.approx(0.2 * 2.0, rel=0.1)
    assert out["yaw"] == pytest.approx(math.pi / 4 * 2.0, rel=0.1)


def test_humanoid_creation_has_10_joints_and_stands():
    out = run_example("humanoid_creation", "--seconds", "2")
    assert out["num_dof"] == 10
    assert out["height_end"] == pytest.approx(out["height_start"], abs=0.03)
    assert (out["limits"][:, 0] < out["limits"][:, 1]).all()


def test_humanoid_walk_cycle_tracks_its_joint_targets():
    out = run_example("humanoid_walk_cycle", "--seconds", "3")
    errors = np.array(list(out["rms_error_rad"].values()))
    assert len(errors) == 10
    assert errors.max() < math.radians(10)


def test_usd_scene_objects_come_to_rest_on_the_table():
    out = run_example("usd_scene", "--seconds", "2")
    assert out["crate_position"][2] == pytest.approx(0.75 + 0.1, abs=0.005)
    assert out["ball_position"][2] == pytest.approx(0.75 + 0.05, abs=0.005)
