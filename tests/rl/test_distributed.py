"""torchrun data-parallel PPO: CPU ranks over gloo run the same code path as GPU ranks over NCCL."""

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from ports import free_port


@pytest.mark.skipif(shutil.which("torchrun", path=str(Path(sys.executable).parent)) is None,
                    reason="torchrun not installed")
def test_two_ranks_train_one_run_and_stop_together(tmp_path):
    torchrun = shutil.which("torchrun", path=str(Path(sys.executable).parent))
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    done = subprocess.run(
        [torchrun, "--nproc-per-node", "2", "--master-addr", "127.0.0.1", "--master-port", str(free_port()),
         "-m", "ambulo.cli", "train", "cartpole", "--num-envs", "128", "--max-iterations", "60",
         "--eval-every", "10", "--stop-at-criterion", "--log-root", str(tmp_path)],
        capture_output=True, text=True, timeout=240, env=env)
    assert done.returncode == 0, done.stderr[-2000:]
    runs = list((tmp_path / "cartpole").iterdir())
    assert len(runs) == 1, f"only rank 0 writes a run folder: {runs}"  # no rank1 folder
    run = runs[0]
    assert json.loads((run / "run.json").read_text())["world_size"] == 2
    reached = json.loads((run / "time_to_criterion.json").read_text())
    rows = list(csv.DictReader(open(run / "metrics.csv")))
    # both ranks stopped at the iteration rank 0 judged: no rank ran on (it would hang in the
    # next all-reduce and torchrun would not return 0) and rank 0 logged nothing after it
    assert int(rows[-1]["iteration"]) == reached["iteration"] < 59
    # the global batch: 2 ranks x 128 envs x 32 steps per iteration
    assert int(rows[0]["env_steps"]) == 2 * 128 * 32
    assert done.stdout.count("training cartpole") == 1 and "x 2 ranks" in done.stdout
