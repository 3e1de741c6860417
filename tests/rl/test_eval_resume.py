"""A resumed run's evaluation records: evals.csv keeps no row of an iteration after the resumed
checkpoint, and time_to_criterion.json is kept only if it predates it."""

import csv
import json
import time

import pytest

from ambulo.rl import train
from ambulo.rl.periodic_eval import EVAL_COLUMNS, TIME_FILE, resume_evals
from ambulo.rl.runs import checkpoints
from ambulo.utils.atomic import TMP_MARK


def _iterations(path):
    return [int(r["iteration"]) for r in csv.DictReader(open(path, newline=""))]


def _write_evals(run_dir, iterations, cut=""):
    with open(run_dir / "evals.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(EVAL_COLUMNS)
        for it in iterations:
            row = [it, 1.0 + it, 64 * (it + 1), "0.500", "2.00", "1.00", "", False]
            writer.writerow(row + [""] * (len(EVAL_COLUMNS) - len(row)))  # the CPU-engine and block cells
        f.write(cut)


def test_resume_drops_later_eval_rows_a_cut_line_and_a_stale_time_to_criterion(tmp_path):
    _write_evals(tmp_path, [1, 3, 5, 7], cut="9,12.")  # a kill cut the row of iteration 9 short
    (tmp_path / TIME_FILE).write_text(json.dumps({"iteration": 5, "checkpoint": "model_5.pt"}))
    # resumed from model_3.pt: iterations 4.. run again
    assert resume_evals(tmp_path, start=4) is None
    assert _iterations(tmp_path / "evals.csv") == [1, 3]
    assert next(csv.reader(open(tmp_path / "evals.csv"))) == list(EVAL_COLUMNS)
    assert not (tmp_path / TIME_FILE).exists()  # it judged model_5, which the resume retrains
    assert not list(tmp_path.glob(f"*{TMP_MARK}*"))  # rewritten through a temporary, none left


def test_resume_keeps_a_success_from_before_the_resumed_checkpoint(tmp_path):
    _write_evals(tmp_path, [1, 3, 5])
    record = {"iteration": 3, "checkpoint": "model_3.pt", "wall_s": 12.5}
    (tmp_path / TIME_FILE).write_text(json.dumps(record))
    assert resume_evals(tmp_path, start=4) == record  # iteration 3 = the resumed checkpoint: kept
    assert json.loads((tmp_path / TIME_FILE).read_text()) == record
    assert _iterations(tmp_path / "evals.csv") == [1, 3]
    (tmp_path / TIME_FILE).write_text("{not json")  # not ambulo's (its writes are atomic): removed
    assert resume_evals(tmp_path, start=4) is None and not (tmp_path / TIME_FILE).exists()


def test_train_resume_with_eval_every_keeps_iterations_unique_and_increasing(tmp_path):
    fast = {"save_interval": 100, "num_steps_per_env": 8}  # checkpoints come from the evaluations
    run_dir = train("cartpole", num_envs=16, max_iterations=4, log_root=tmp_path, eval_every=1,
                    ppo_overrides=fast)
    assert _iterations(run_dir / "evals.csv") == [0, 1, 2, 3]
    # as if the run had died after evaluating iteration 3 with its last two checkpoints lost:
    # the resume goes back to model_1.pt and runs iterations 2 and 3 again
    (run_dir / "model_2.pt").unlink()
    (run_dir / "model_3.pt").unlink()
    (run_dir / TIME_FILE).write_text(json.dumps({"iteration": 3, "checkpoint": "model_3.pt", "stale": True}))
    train("cartpole", resume=run_dir, log_root=tmp_path, eval_every=1)
    assert [it for it, _ in checkpoints(run_dir)] == [0, 1, 2, 3]
    assert _iterations(run_dir / "evals.csv") == [0, 1, 2, 3]
    assert _iterations(run_dir / "metrics.csv") == [0, 1, 2, 3]
    timed = run_dir / TIME_FILE
    assert not timed.exists() or "stale" not in json.loads(timed.read_text())


@pytest.mark.parametrize("algo", ["ppo", "fast-td3"])
def test_a_resumed_run_counts_the_wall_time_of_its_earlier_segments(tmp_path, algo):
    """A run stopped and resumed reports the time to a criterion of the whole run: the first
    segment here is made to look 1,000 s long, so the resumed segment's evaluations must say so."""
    short = {"ppo_overrides": {"save_interval": 100, "num_steps_per_env": 8}} if algo == "ppo" else {}
    run_dir = train("cartpole", algo=algo, num_envs=16 if algo == "ppo" else 8, max_iterations=2,
                    log_root=tmp_path, eval_every=1, started_s=time.monotonic() - 1000.0, **short)
    train("cartpole", resume=run_dir, max_iterations=4, log_root=tmp_path, eval_every=1)
    rows = list(csv.DictReader(open(run_dir / "evals.csv")))
    assert [int(r["iteration"]) for r in rows] == [0, 1, 2, 3]
    walls = [float(r["wall_s"]) for r in rows]
    assert all(w >= 1000.0 for w in walls), walls
    assert walls == sorted(walls), walls
