"""benchmarks/offpolicy_iteration.py runs on the CPU (cartpole) and its ceilings follow from its halves."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _run(*flags: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]),
           "OMP_NUM_THREADS": "1"}
    return subprocess.run([sys.executable, str(ROOT / "benchmarks" / "offpolicy_iteration.py"), "--device", "cpu",
                           "--task", "cartpole", "--num-envs", "16", *flags], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=300)


def test_each_variant_is_timed_against_the_halves_measured_in_the_same_run():
    run = _run("--iterations", "3", "--warmup", "3", "--modes", "base,overlap")
    assert run.returncode == 0, run.stderr[-3000:]
    (line,) = [x for x in run.stdout.splitlines() if x.startswith("RESULT ")]
    result = json.loads(line[len("RESULT "):])
    assert list(result["modes"]) == ["base", "overlap"] and result["steps_per_it"] == 8
    env_s, updates_s = result["env_s_per_step"], result["updates_s_per_step"]
    assert env_s > 0 and updates_s > 0
    assert result["sequential_s_per_it"] == pytest.approx(8 * (env_s + updates_s), rel=1e-3, abs=1e-5)
    assert result["overlap_ideal_s_per_it"] == pytest.approx(8 * max(env_s, updates_s), rel=1e-3, abs=1e-5)
    for row in result["modes"].values():
        assert row["ratio"] == pytest.approx(result["overlap_ideal_s_per_it"] / row["s_per_it"], abs=2e-3)


def test_an_unknown_variant_is_refused_in_one_line():
    run = _run("--modes", "base,fused")
    assert run.returncode != 0 and "--modes fused: unknown" in run.stderr and "both" in run.stderr
