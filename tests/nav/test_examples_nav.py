"""The navigation examples run headless and produce what they say."""

from pathlib import Path

import pytest

from script_loader import run_main

NAV_EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "nav"


def run_nav_example(file_name: str, *argv: str) -> dict:
    return run_main(NAV_EXAMPLES / file_name, *argv)


def test_preview_walk_pattern_draws_a_balanced_walk(tmp_path):
    pytest.importorskip("matplotlib")
    png = tmp_path / "walk.png"
    out = run_nav_example("preview_walk_pattern.py", "--steps", "4", "--png", str(png))
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    # 4 steps of 0.2 m, the last one closing the stance: the CoM comes to rest over x = 0.6 m
    assert out["com_travel_m"] == pytest.approx(0.6, abs=2e-3)
    assert out["max_zmp_error_m"] < 5e-3
    assert out["min_zmp_margin_m"] > 0.02


def test_walk_footsteps_walks_the_plan_in_mujoco(tmp_path):
    pytest.importorskip("matplotlib")
    png = tmp_path / "walk.png"
    out = run_nav_example("walk_footsteps.py", "--distance", "1", "--turn-deg", "45", "--seed", "1", "--png", str(png))
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    summary = out["summary"]
    assert not summary["fell"]
    assert summary["zmp_inside_single_support"] >= 0.95
    assert summary["capture_inside_all"]
    assert summary["distance_m"] == pytest.approx(1.0, abs=0.08)
    assert summary["turn_deg"] == pytest.approx(45.0, abs=5.0)
