"""The GPU benchmarks run end to end on Warp's CPU device with a few envs and print a RESULT
line that parses; their checks that need no GPU hold (benchmarks/gpu_suite.sh runs them on one).
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("mujoco_warp")

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"


def run_benchmark(script: str, *args: str) -> dict:
    """Run ``benchmarks/<script>`` on the CPU as a subprocess; return its parsed RESULT line."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])}
    run = subprocess.run([sys.executable, str(BENCHMARKS / script), "--device", "cpu", *args],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, f"{script} failed:\n{run.stdout[-2000:]}\n{run.stderr[-4000:]}"
    lines = [line for line in run.stdout.splitlines() if line.startswith("RESULT ")]
    assert len(lines) == 1, f"{script} printed {len(lines)} RESULT lines:\n{run.stdout[-2000:]}"
    return json.loads(lines[0][len("RESULT "):])


def test_env_gpu_measures_env_against_an_exact_replay():
    result = run_benchmark("env_gpu.py", "--num-envs", "4", "--steps", "3", "--warmup", "2", "--repeats", "1")
    (row,) = result["sizes"]
    assert row["num_envs"] == 4
    assert row["env_steps_per_s"] > 0 and row["raw_physics_steps_per_s"] > 0
    # both figures are rounded to whole steps/s
    assert abs(row["physics_steps_per_s"] - row["env_steps_per_s"] * result["decimation"]) <= result["decimation"]
    assert result["ratio"] == row["ratio"] > 0
    # the ceiling redoes the env's physics: on Warp's CPU device the replay is bit for bit
    assert row["replay_match"] == 1.0
    assert result["target"]["ratio"] is None  # no 4096-env row in this run
    assert {"torch", "warp", "mujoco", "mujoco_warp"} <= set(result["versions"])


def test_profile_gpu_splits_the_step_and_counts_round_trips(tmp_path):
    trace = tmp_path / "trace.json"
    result = run_benchmark("profile_gpu.py", "--num-envs", "4", "--steps", "3", "--warmup", "2",
                           "--trace", str(trace))
    host = result["host_ms_per_step"]
    assert 0 < host["physics_launch"] < host["total"]
    assert 0 < host["torch_ops"] < host["total"]
    assert host["physics_launch"] + host["torch_ops"] + host["python_other"] == pytest.approx(host["total"], abs=0.01)
    assert result["host_round_trips"]["sync_calls_per_step"] == 0  # no CUDA on this run
    assert result["device_ms_per_step"] is None
    assert json.loads(trace.read_text())["traceEvents"]


@pytest.mark.skipif(not (BENCHMARKS / "render_gpu.py").exists(), reason="benchmarks/render_gpu.py not written yet")
def test_render_gpu_runs_on_the_cpu():
    result = run_benchmark("render_gpu.py", "--num-worlds", "2", "--width", "16", "--height", "12",
                           "--steps", "2", "--repeats", "1")
    assert result["ratio"] > 0


def test_sim_to_sim_finds_the_engines_agreeing_from_walking_states():
    """From states of the shipped policy walking: the same contacts per foot, forces and one-step
    states within float32 noise; the options differ only in MuJoCo Warp's float32 tolerance."""
    result = run_benchmark("sim_to_sim.py", "--worlds", "2", "--warmup", "10", "--record", "4",
                           "--stride", "2", "--horizon", "4")
    assert result["samples"] >= 2
    differ = {k for k, v in result["options"].items() if v["warp"] is not None
              and abs(v["mujoco"] - v["warp"]) > 1e-6 * max(abs(v["mujoco"]), 1e-12)}
    assert differ == {"tolerance"}
    at = result["at_state"]
    assert at["feet_with_different_contact_count"] == 0.0
    assert at["contacts_per_foot_mean"]["mujoco"] > 0
    assert at["normal_force_rel_diff_p90"] < 1e-3
    step = result["divergence_from_mujoco"]["warp"]["step_4"]
    assert step["qpos_max_abs_p90"] < 1e-5 and step["qvel_max_abs_p90"] < 1e-3
