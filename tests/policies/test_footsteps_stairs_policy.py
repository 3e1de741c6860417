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
