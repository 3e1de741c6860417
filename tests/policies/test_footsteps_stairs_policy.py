"""The shipped stairs footstep walker (humanoid-footsteps-stairs, trained on MuJoCo Warp) on the CPU engine: over
0.10 m steps up and down it puts its feet on its footsteps within the task's 5 cm and does not fall, as
``ambulo eval --shipped`` judges it (the sim-to-sim check of a GPU-trained walker)."""

from ambulo.rl.evaluate import evaluate_shipped

TASK = "humanoid-footsteps-stairs"


def test_meets_places_feet_over_stairs_on_the_cpu_engine():
    result = evaluate_shipped(TASK, num_episodes=8, episode_length_s=8.0, device="cpu", quiet=True)
    assert result["fall_rate"] == 0.0
    assert result["mean_placement_error_m"] <= 0.05
    assert result["mean_touchdowns_per_s"] > 2.0  # it steps along its plan, not stands on one foot
    assert result["places_feet"]
    assert {"stairs_up", "stairs_down"} <= set(result["by_kind"])  # both directions were walked


def test_the_figure_script_draws_a_climb_out_of_the_pit(tmp_path):
    """``scripts/footsteps_figure.py --task humanoid-footsteps-stairs``: the planner plans on the terrain's heights
    out of a pit of 0.10 m risers and the shipped walker steps on it (the committed PNG is its default output)."""
    import importlib.util
    from pathlib import Path

    import numpy as np

    path = Path(__file__).resolve().parents[2] / "scripts" / "footsteps_figure.py"
    spec = importlib.util.spec_from_file_location("footsteps_figure", path)
    figure = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(figure)
    out = figure.main(["--task", TASK, "--seconds", "6", "--out", str(tmp_path / "climb.png")])
    assert out.stat().st_size > 10_000
    result = figure.walk((2.6, 0.0, 0.0), 6.0, task=TASK)
    assert result["climbed_m"] >= 0.2 - 1e-6  # the plan crosses two 0.10 m risers or more
    hits = result["errors"][result["errors"] <= result["advance_radius_m"]]
    assert not result["fell"] and len(hits) >= 6 and np.median(hits) <= 0.05
