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
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)  # minutes on a loaded 2-core machine
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
    # it times training's rollout step on the runner `ambulo train` builds, never a stand-in MLP
    assert row["policy"].startswith("AmbuloRunner rollout step: rsl-rl-lib MLPModel")
    assert "SyncFreeGaussian" in row["policy"] and result["policy"] == row["policy"]
    assert row["syncs"] is None  # counted on CUDA only
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
    assert result["policy"].startswith("AmbuloRunner rollout step") and result["torch_sync_warnings"] is None
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


def test_cuda_test_selection_records_what_ran_passed_failed_and_skipped(tmp_path):
    """benchmarks/cuda_tests.py (gpu_suite.sh's test part) keeps the tests marked as CUDA tests
    either way the project marks them, drops the rest, and reports each outcome."""
    (tmp_path / "test_marked.py").write_text(
        "import pytest\n"
        "pytestmark = pytest.mark.skipif(True, reason='needs CUDA')\n"
        "def test_on_the_gpu():\n    pass\n")
    (tmp_path / "test_device_variable.py").write_text(
        "import os\n"
        "DEVICE = os.environ.get('AMBULO_TEST_DEVICE', 'cpu')\n"
        "def test_passes():\n    assert DEVICE == 'cuda'\n"
        "def test_fails():\n    assert DEVICE == 'cpu', 'ran on ' + DEVICE\n")
    (tmp_path / "test_plain.py").write_text(
        "import pytest\n"
        "@pytest.mark.skipif(True, reason='needs a display')\n"
        "def test_cpu_only():\n    pass\n"
        "def test_other():\n    pass\n")
    report = tmp_path / "report.json"
    env = {**os.environ, "PYTHONPATH": str(BENCHMARKS), "AMBULO_TEST_DEVICE": "cuda"}
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "cuda_tests",
                          "--cuda-report", str(report), str(tmp_path)],
                         cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert run.returncode == 1, run.stdout[-2000:]  # one test fails on purpose
    result = json.loads(report.read_text())
    outcomes = {name.split("::")[-1]: row["outcome"] for name, row in result["tests"].items()}
    assert outcomes == {"test_on_the_gpu": "skipped", "test_passes": "passed", "test_fails": "failed"}
    assert result["selected"] == 3 and result["deselected"] == 2 and result["not_run"] == []
    assert result["summary"] == {"skipped": 1, "passed": 1, "failed": 1, "not_run": 0}
    assert result["test_device"] == "cuda"
    failed = next(row for name, row in result["tests"].items() if name.endswith("test_fails"))
    assert "ran on cuda" in failed["reason"]


@pytest.mark.slow
def test_issue25_device_script_runs_on_the_cpu(tmp_path):
    """benchmarks/issue25_device.sh end to end on Warp's CPU device (ISSUE25_SMOKE=1)."""
    env = {**os.environ, "ISSUE25_SMOKE": "1", "ISSUE25_BUDGET_S": "1500", "PYTHON": sys.executable}
    run = subprocess.run(["bash", str(BENCHMARKS / "issue25_device.sh"), str(tmp_path)], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert {p: s["status"] for p, s in summary["parts"].items()} == {
        "sync_test": "ok", "env_gpu": "ok", "profile_gpu": "ok", "gpu_suite": "ran"}
    assert summary["sync_test"]["summary"]["skipped"] == 2  # no CUDA here
    assert summary["env_gpu"]["ratio"] > 0 and summary["profile"]["policy"].startswith("AmbuloRunner")
    # the suite's tests part only collects in a smoke run: every selected GPU test is listed, none ran
    tests = summary["gpu_tests"]
    assert tests["selected"] >= 10 and tests["summary"]["not_run"] == tests["selected"]
    assert not any("test_sync_free_gpu" in name for name in tests["not_run"])
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file()) == sorted(
        ["summary.json", "sync_test.json", "sync_test.log", "env_gpu.log", "profile_gpu.log", "suite.log",
         "results.json", "gpu_tests.json"])


@pytest.mark.slow
def test_render_tiers_gpu_runs_on_the_cpu():
    """benchmarks/render_tiers_gpu.py at a tiny size on lavapipe and Mitsuba's LLVM variant: pbr from
    one and from two processes at once (each its frames behind a barrier), raster and the path tier
    per frame, judged against the CPU targets (~1.5 min on a loaded 2-core machine)."""
    from ambulo.render.pbr import _vulkan_problem

    pytest.importorskip("mitsuba")
    if _vulkan_problem() is not None:
        pytest.skip(_vulkan_problem())
    result = run_benchmark("render_tiers_gpu.py", "--width", "64", "--height", "48", "--frames", "3",
                           "--path-frames", "2", "--path-spp", "2", "--warmup", "1", "--pbr-processes", "2")
    tiers = result["tiers"]
    assert result["gpu"] is False and result["target"]["pbr_fps"] == 8.0 and result["target"]["path_fps"] == 1.0
    assert result["target"]["settings_match"] is False  # 64x48 is not the target's size
    assert tiers["pbr_1_process"]["processes"] == 1 and tiers["pbr_1_process"]["frames"] == 3
    two = result["pbr_by_processes"]["2"]
    assert two["processes"] == 2 and two["frames"] == 6
    # every process renders its frames inside the aggregate's wall time
    assert two["wall_s"] >= two["slowest_process_s"] > 0
    assert two["fps"] == pytest.approx(6 / two["wall_s"], rel=0.01)
    assert tiers["pbr"]["fps"] == max(r["fps"] for r in result["pbr_by_processes"].values())
    assert tiers["raster"]["frames"] == 3 and tiers["raster"]["ratio_to_raster"] == 1.0
    path = tiers["path"]
    assert path["frames"] == 2 and path["spp"] == 2 and path["denoise"] and path["variant"] == "llvm_ad_rgb"
    assert result["meets_pbr"] == (tiers["pbr"]["fps"] >= 8.0)
    assert result["meets_path"] == (path["fps"] >= 1.0)
    assert tiers["pbr"]["ratio_to_raster"] == pytest.approx(tiers["pbr"]["fps"] / tiers["raster"]["fps"], abs=1e-3)


def test_eval_gpu_times_an_evaluation_of_the_shipped_walker():
    # off CUDA there is no graph: the eager evaluation alone, with the metrics ``ambulo eval`` reports
    result = run_benchmark("eval_gpu.py", "--num-episodes", "4", "--episode-length-s", "0.5")
    assert result["device"] == "cpu" and result["steps"] == 25 and result["eager_s"] > 0
    assert result["eager_metrics"]["fall_rate"] == 0.0  # the shipped walker stands for half a second
    assert 0.0 < result["eager_metrics"]["mean_abs_vel_error_m_s"] < 1.0
    assert "graph_s" not in result


@pytest.mark.slow  # three cold compiles of cartpole's kernels: ~1 min on 2 free cores
def test_warp_compile_times_serial_parallel_and_a_warm_cache():
    result = run_benchmark("warp_compile.py", "--task", "cartpole", "--num-envs", "2", "--workers", "0,2",
                           "--driver-cache")
    runs = result["runs"]
    assert runs["serial"]["precompiled_modules"] == 0 < runs["parallel"]["precompiled_modules"]
    # the warm run finds the parallel run's cache: it compiles nothing, so it is the fastest
    assert runs["warm"]["engine_compile_s"] < runs["parallel"]["engine_compile_s"]
    assert result["speedup"] == round(result["seconds"]["serial"] / result["seconds"]["parallel"], 3)
    # --driver-cache: two more runs, each from an empty Warp cache of its own (they compile as much as the
    # parallel run, not a warm run's nothing); on the CPU no CUDA format is reported
    for name in ("parallel_driver_cold", "parallel_driver_warm"):
        assert runs[name]["precompiled_modules"] == runs["parallel"]["precompiled_modules"]
        assert runs[name]["engine_compile_s"] > 2 * runs["warm"]["engine_compile_s"], name
    assert result["cuda_output"] is None and runs["serial"]["cuda_output"] is None


def test_warp_compile_refuses_workers_that_are_not_two_numbers():
    run = subprocess.run([sys.executable, str(BENCHMARKS / "warp_compile.py"), "--workers", "8"],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode != 0
    assert "--workers '8': give two whole numbers, serial first" in run.stderr


def test_warp_compile_names_an_unknown_task_before_any_run():
    run = subprocess.run([sys.executable, str(BENCHMARKS / "warp_compile.py"), "--task", "humanoid-ruff"],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode != 0
    assert "--task: no task named 'humanoid-ruff'" in run.stderr and "humanoid-rough" in run.stderr
