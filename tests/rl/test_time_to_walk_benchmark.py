"""benchmarks/time_to_walk.py runs end to end on the CPU (cartpole) and reports what it measured."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from script_loader import load_script

ROOT = Path(__file__).resolve().parents[2]


def test_time_to_walk_reports_each_seed_from_its_run_folder(tmp_path):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]),
           "OMP_NUM_THREADS": "1"}
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "time_to_walk.py"), "--task", "cartpole",
                          "--device", "cpu", "--seeds", "0", "--num-envs", "256", "--eval-every", "10",
                          "--max-minutes", "3", "--no-ceiling", "--out", str(tmp_path)],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=240)
    assert run.returncode == 0, run.stderr[-3000:]
    (line,) = [x for x in run.stdout.splitlines() if x.startswith("RESULT ")]
    result = json.loads(line[len("RESULT "):])
    assert result["reached"] == "1/1"
    seed = result["runs"]["0"]
    reached = json.loads(next(tmp_path.glob("seed0/cartpole/*/time_to_criterion.json")).read_text())
    # the reported minutes are the run's own measurement, not a separate clock
    assert seed["minutes"] == round(reached["wall_s"] / 60, 2) == result["minutes_median"]
    assert seed["iteration"] == reached["iteration"] and seed["eval"]["balances"] is True
    assert seed["train_env_steps_per_s"] > 0 and seed["iterations"] == reached["iteration"] + 1


def _time_to_walk_module():
    return load_script(ROOT / "benchmarks" / "time_to_walk.py")


def test_gpu_ids_are_read_through_an_inherited_device_mask():
    ttw = _time_to_walk_module()
    assert ttw.child_visible_devices(["0", "1"], None) == "0,1"
    assert ttw.child_visible_devices(["0"], "") == "0"
    # the parent sees physical GPUs 1 and 3 as 0 and 1: the child must get the physical ids
    assert ttw.child_visible_devices(["0"], "1") == "1"
    assert ttw.child_visible_devices(["1", "0"], "1, 3") == "3,1"


def test_gpu_ids_beyond_the_inherited_mask_are_refused_in_one_line():
    ttw = _time_to_walk_module()
    with pytest.raises(SystemExit) as refused:
        ttw.child_visible_devices(["0", "2"], "1,3")
    message = str(refused.value)
    assert "\n" not in message and "--gpu-ids 2" in message and "0..1" in message


def test_start_up_is_the_wall_time_neither_training_nor_evaluating(tmp_path):
    """By hand: met at 12.5 s, iteration 1, 2.0 s of evaluations; iterations 0 and 1 took 1.5 + 0.5 and
    0.25 + 0.25 s (iteration 2, after the criterion, does not count): start-up 12.5 - 2.0 - 2.5 = 8.0 s."""
    run = tmp_path / "cartpole" / "2026-12-01_00-00-00"
    run.mkdir(parents=True)
    (run / "run.json").write_text("{}")
    (run / "time_to_criterion.json").write_text(json.dumps(
        {"wall_s": 12.5, "iteration": 1, "env_steps": 64, "eval": {}, "eval_s_included": 2.0}))
    (run / "metrics.csv").write_text("iteration,env_steps,collect_s,learn_s\n0,32,1.5,0.5\n1,64,0.25,0.25\n"
                                     "2,96,9.0,9.0\n")
    summary = _time_to_walk_module().run_summary(tmp_path)
    assert summary["reached"] and summary["startup_s"] == 8.0


def test_start_up_of_a_run_judged_in_the_background_counts_to_the_judged_save(tmp_path):
    """By hand: iteration 1's checkpoint saved at 11.0 s, its verdict at 12.5 s (training went on:
    iteration 2's 18 s are past it); 0.1 s of saving: start-up 11.0 - 0.1 - 2.5 = 8.4 s, lag 1.5 s."""
    run = tmp_path / "cartpole" / "2026-12-01_00-00-00"
    run.mkdir(parents=True)
    (run / "run.json").write_text("{}")
    (run / "time_to_criterion.json").write_text(json.dumps(
        {"wall_s": 12.5, "iteration": 1, "env_steps": 64, "eval": {}, "eval_s_included": 0.1,
         "eval_async": True, "checkpoint_wall_s": 11.0}))
    (run / "metrics.csv").write_text("iteration,env_steps,collect_s,learn_s\n0,32,1.5,0.5\n1,64,0.25,0.25\n"
                                     "2,96,9.0,9.0\n")
    summary = _time_to_walk_module().run_summary(tmp_path)
    assert summary["minutes"] == round(12.5 / 60, 2)  # the time to the criterion is the verdict's
    assert summary["startup_s"] == 8.4 and summary["verdict_lag_s"] == 1.5 and summary["eval_async"]
