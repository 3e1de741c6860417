"""Training survives interruption, and the RL commands answer bad input in one line.

Signals go to real ``python -m ambulo.cli train cartpole`` processes; the rest runs in this
process on a small cartpole run (16 envs, 4 steps an iteration: each iteration takes ~20 ms,
and no untrained pole falls within 4 steps of a reset, which the window test relies on).
"""

from __future__ import annotations

import csv
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import imageio_ffmpeg
import pytest
import torch

from ambulo.cli import main
from ambulo.rl import TrainingInterrupted, runs, train
from ambulo.rl.checkpoints import CheckpointError, checkpoints, find_checkpoint
from ambulo.rl.metrics import MetricsCsv
from ambulo.rl.vecenv import RslRlVecEnv
from ambulo.utils.atomic import atomic_open

FAST = {"save_interval": 1, "num_steps_per_env": 4}


def rows(run_dir: Path) -> list[dict[str, str]]:
    with open(run_dir / "metrics.csv", newline="") as f:
        return list(csv.DictReader(f))


def iterations(run_dir: Path) -> list[int]:
    return [int(r["iteration"]) for r in rows(run_dir)]


RUN_FILES = re.compile(r"^(model_\d+\.pt|metrics\.csv|run\.json|eval\.json|events\.out\..*|git)$")


def assert_checkpoints_load(run_dir: Path, temporaries_allowed: bool = False) -> list[int]:
    """Every checkpoint of the run loads and holds its own iteration; no temporaries remain
    (``temporaries_allowed``: right after a SIGKILL, which may land inside a checkpoint write)."""
    found = checkpoints(run_dir)
    for it, path in found:
        assert torch.load(path, weights_only=False)["iter"] == it
    if not temporaries_allowed:
        assert not [p.name for p in run_dir.iterdir() if not RUN_FILES.match(p.name)]
    return [it for it, _ in found]


def leave_a_partial_write(path: Path) -> None:
    """What a run killed while writing ``path`` leaves: an atomic write's temporary file."""
    code = ("import os, sys; from ambulo.utils.atomic import atomic_open\n"
            "writing = atomic_open(sys.argv[1], fsync=True); f = writing.__enter__()\n"
            "f.write(b'x' * 1000)\n"
            "f.flush(); os.kill(os.getpid(), 9)")
    subprocess.run([sys.executable, "-c", code, str(path)])
    assert not path.exists() and len(list(path.parent.iterdir())) > 0


def truncate(path: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def one_line(capsys, command: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    errors = [line for line in err if line.startswith(f"ambulo {command}: error: ")]
    assert len(errors) == 1 and "Traceback" not in "\n".join(err), err
    return errors[0]


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A finished 4-iteration run with model_0..3.pt; tests copy it before changing it."""
    root = tmp_path_factory.mktemp("runs")
    return train("cartpole", num_envs=16, max_iterations=4, log_root=root, ppo_overrides=FAST)


@pytest.fixture
def run_copy(trained, tmp_path):
    """A copy of ``trained`` under ``tmp_path/runs/cartpole/``, returned with its log root."""
    root = tmp_path / "runs"
    copy = root / "cartpole" / trained.name
    shutil.copytree(trained, copy)
    return copy, root


# --- signals, in real processes --------------------------------------------------------------


def start_training(root: Path, *extra: str, rows_before: int = 3) -> tuple[subprocess.Popen, Path]:
    """``ambulo train cartpole`` in a subprocess, returned once ``rows_before`` iterations are
    in its metrics.csv (the training loop is running)."""
    cmd = [sys.executable, "-m", "ambulo.cli", "train", "cartpole", "--num-envs", "16",
           "--max-iterations", "100000", "--log-root", str(root),
           "--ppo-cfg", "num_steps_per_env=4", *extra]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and proc.poll() is None:
        found = list(root.glob("cartpole/*/metrics.csv"))
        if found and len(found[0].read_text().splitlines()) > rows_before:
            return proc, found[0].parent
        time.sleep(0.02)
    proc.kill()
    pytest.fail(f"training did not start: {proc.communicate()[1][-2000:]}")


@pytest.mark.parametrize("sig, status", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_saves_a_checkpoint_and_says_how_to_resume(tmp_path, sig, status):
    proc, run_dir = start_training(tmp_path, "--ppo-cfg", "save_interval=100000")
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == status, err[-2000:]
    last = iterations(run_dir)[-1]
    # the iteration under way finished, was logged once and saved (besides rsl-rl's model_0)
    assert iterations(run_dir) == list(range(last + 1))
    assert assert_checkpoints_load(run_dir) == [0, last]
    line = err.strip().splitlines()[-1]
    assert line == (f"ambulo train: stopped by {sig.name}: saved model_{last}.pt in {run_dir}; "
                    f"continue with `ambulo train --resume {run_dir}`")
    assert "Traceback" not in err


def test_sigkill_loses_only_the_iterations_after_the_last_checkpoint(tmp_path):
    proc, run_dir = start_training(tmp_path, "--ppo-cfg", "save_interval=3", rows_before=7)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    logged = iterations(run_dir)[-1]
    saved = assert_checkpoints_load(run_dir, temporaries_allowed=True)
    assert saved[-1] % 3 == 0 and logged - saved[-1] < 3 + 1  # at most the unsaved ones lost
    checkpoint_reward = rows(run_dir)[saved[-1]]["mean_reward"]
    leave_a_partial_write(run_dir / f"model_{logged + 1}.pt")
    assert [p for p in run_dir.iterdir() if not RUN_FILES.match(p.name)]

    train(resume=run_dir, max_iterations=logged + 3)
    # iterations after the checkpoint were run again and logged once: no duplicate rows
    assert iterations(run_dir) == list(range(logged + 3))
    table = rows(run_dir)
    assert all(value.lower() != "nan" for row in table for value in row.values())
    # the 100-episode window came back with the checkpoint: no pole falls within the first
    # resumed iteration, yet its mean reward is the checkpoint's, not empty
    assert table[saved[-1] + 1]["mean_reward"] == checkpoint_reward != ""
    assert assert_checkpoints_load(run_dir)[-1] == logged + 2


def test_a_second_signal_during_the_save_stops_at_once_and_corrupts_nothing(
        run_copy, monkeypatch):
    run_dir, _ = run_copy
    real_step = RslRlVecEnv.step
    steps = {"n": 0}

    def step(self, actions):  # Ctrl-C in the middle of the second resumed iteration
        steps["n"] += 1
        if steps["n"] == 6:
            os.kill(os.getpid(), signal.SIGINT)
        return real_step(self, actions)

    def save_cut_short(obj, path):  # after that, Ctrl-C again while model_5.pt is half written
        with atomic_open(path, fsync=True) as f:
            if steps["n"] >= 6:
                f.write(b"half a checkpoint")
                os.kill(os.getpid(), signal.SIGINT)
            torch.save(obj, f)

    monkeypatch.setattr(RslRlVecEnv, "step", step)
    monkeypatch.setattr(runs, "atomic_torch_save", save_cut_short)
    # what the handler was: Python's default_int_handler, or SIG_IGN when pytest was started in the
    # background by a non-interactive shell (which ignores SIGINT for its background jobs)
    handler_before = signal.getsignal(signal.SIGINT)
    with pytest.raises(TrainingInterrupted) as stopped:
        train(resume=run_dir, max_iterations=50)
    monkeypatch.undo()
    assert not stopped.value.saved and stopped.value.exit_status == 130
    assert "stopped at once by a second SIGINT" in str(stopped.value)
    assert "the newest checkpoint is model_4.pt" in str(stopped.value)
    assert assert_checkpoints_load(run_dir) == [0, 1, 2, 3, 4]  # model_5.pt never appeared
    assert iterations(run_dir) == [0, 1, 2, 3, 4, 5]
    assert signal.getsignal(signal.SIGINT) is handler_before  # handlers restored


# --- metrics.csv ----------------------------------------------------------------------------


def test_metrics_resume_drops_later_rows_and_a_cut_line(tmp_path):
    path = tmp_path / "metrics.csv"
    metrics = MetricsCsv(path)
    for it in range(5):
        metrics.append(it, 64, 1.0 + it, 0.5, 0.01, 0.02, 1.0)
    with open(path, "a") as f:
        f.write("1")  # a kill cut the row of iteration 1x short after its first digit
    MetricsCsv(path, start=3).append(3, 64, None, float("nan"), 0.01, 0.02, 1.0)
    table = list(csv.DictReader(open(path, newline="")))
    assert [r["iteration"] for r in table] == ["0", "1", "2", "3"]
    assert [r["mean_reward"] for r in table] == ["1.0000", "2.0000", "3.0000", ""]
    assert table[-1]["mean_episode_length_s"] == ""  # no mean yet: empty, never "nan"


# --- corrupt checkpoints --------------------------------------------------------------------


def test_resume_falls_back_past_a_truncated_checkpoint(run_copy, capsys):
    run_dir, _ = run_copy
    truncate(run_dir / "model_3.pt")
    train(resume=run_dir, max_iterations=5)
    captured = capsys.readouterr()
    assert (f"warning: checkpoint {run_dir / 'model_3.pt'} is unreadable (truncated or corrupt"
            in captured.err) and "using model_2.pt" in captured.err
    assert f"resuming {run_dir} from model_2.pt at iteration 3" in captured.out
    assert assert_checkpoints_load(run_dir) == [0, 1, 2, 3, 4]  # model_3.pt written anew
    assert iterations(run_dir) == [0, 1, 2, 3, 4]


def test_eval_names_a_corrupt_checkpoint_and_uses_the_previous(run_copy, capsys):
    run_dir, _ = run_copy
    truncate(run_dir / "model_3.pt")
    assert main(["eval", str(run_dir), "--episodes", "2"]) == 0
    assert "model_3.pt is unreadable" in capsys.readouterr().err
    assert json.loads((run_dir / "eval.json").read_text())["checkpoint"] == "model_2.pt"


def test_a_corrupt_named_checkpoint_or_run_is_one_line(run_copy, capsys):
    run_dir, _ = run_copy
    before = (run_dir / "model_1.pt").read_bytes()
    (run_dir / "model_1.pt").write_bytes(before[:100])
    assert main(["export", str(run_dir), "--checkpoint", "1"]) == 2
    line = one_line(capsys, "export")
    assert f"checkpoint {run_dir / 'model_1.pt'} is unreadable (truncated or corrupt" in line
    assert not (run_dir / "exported").exists()
    for _, path in checkpoints(run_dir):
        truncate(path)
    assert main(["train", "--resume", str(run_dir)]) == 2
    line = one_line(capsys, "train")
    assert f"cannot resume: no readable checkpoint in {run_dir}" in line
    assert "model_0.pt, model_1.pt, model_2.pt, model_3.pt" in line
    assert iterations(run_dir) == [0, 1, 2, 3]  # nothing was rewritten


# --- a run that stopped before its first checkpoint ------------------------------------------


def test_a_run_without_checkpoint_does_not_shadow_good_runs(run_copy, capsys):
    run_dir, root = run_copy
    crashed = root / "cartpole" / "9999-01-01_00-00-00"  # newer than the good run
    crashed.mkdir()
    shutil.copy(run_dir / "run.json", crashed / "run.json")
    assert main(["eval", "cartpole", "--episodes", "2", "--log-root", str(root)]) == 0
    err = capsys.readouterr().err
    assert f"note: using {run_dir}; skipping newer {crashed.name}" in err
    assert (run_dir / "eval.json").is_file() and not (crashed / "eval.json").exists()

    assert main(["train", "--resume", str(crashed)]) == 2
    line = one_line(capsys, "train")
    assert f"cannot resume: run {crashed} has no checkpoint" in line
    assert "stopped before its first save; start a new run with `ambulo train cartpole`" in line

    shutil.rmtree(run_dir)
    assert main(["play", "cartpole", "--log-root", str(root)]) == 2
    assert "no run of task 'cartpole'" in one_line(capsys, "play")


# --- --checkpoint NAME and --resume with other settings --------------------------------------


def test_checkpoint_names_are_looked_up_in_the_run_folder(run_copy, tmp_path, monkeypatch, capsys):
    run_dir, _ = run_copy
    monkeypatch.chdir(tmp_path)  # not the run folder: names must be found in it anyway
    for name in ("model_2.pt", "2", str(run_dir / "model_2.pt")):
        assert find_checkpoint(run_dir, name) == run_dir / "model_2.pt"
    assert main(["eval", str(run_dir), "--checkpoint", "1", "--episodes", "2"]) == 0
    assert json.loads((run_dir / "eval.json").read_text())["checkpoint"] == "model_1.pt"
    with pytest.raises(CheckpointError, match="model_0.pt, model_1.pt, model_2.pt, model_3.pt"):
        find_checkpoint(run_dir, "7")
    assert main(["play", str(run_dir), "--checkpoint", "model_7.pt"]) == 2
    line = one_line(capsys, "play")
    assert "checkpoint 'model_7.pt' not found" in line and "model_3.pt" in line


def test_resume_with_other_num_envs_or_seed_keeps_the_runs_and_says_so(run_copy, capsys):
    run_dir, _ = run_copy
    before = (run_dir / "run.json").read_text()
    assert main(["train", "--resume", str(run_dir), "--num-envs", "32", "--seed", "5",
                 "--max-iterations", "5"]) == 0
    out = capsys.readouterr().out
    assert ("resume keeps the run's num_envs 16, seed 0 (run.json), not num_envs 32, seed 5; "
            "start a new run to change them") in out
    assert (run_dir / "run.json").read_text() == before
    assert rows(run_dir)[-1]["env_steps"] == str(5 * 16 * 4)  # 16 envs ran, not 32


# --- the RL commands' numbers, outputs and missing runs --------------------------------------


@pytest.mark.parametrize("argv", [
    ["train", "cartpole", "--num-envs", "0"], ["train", "cartpole", "--num-envs", "2.5"],
    ["train", "cartpole", "--max-iterations", "-3"],
    ["play", "cartpole", "--width", "0"], ["play", "cartpole", "--height", "1.5"],
    ["play", "cartpole", "--seconds", "0"], ["play", "cartpole", "--seconds", "nan"],
    ["eval", "cartpole", "--episodes", "0"], ["eval", "cartpole", "--episodes", "ten"],
    ["eval", "cartpole", "--episode-length-s", "-1"],
])
def test_bad_numbers_are_one_line_with_the_fix(argv, capsys, tmp_path):
    with pytest.raises(SystemExit) as exit_:
        main([*argv, "--log-root", str(tmp_path)])
    assert exit_.value.code == 2
    line = one_line(capsys, argv[0])
    flag, value = argv[-2], argv[-1]
    assert f"argument {flag}: {value!r} is not a" in line and "above 0; give e.g. " + flag in line
    assert not list(tmp_path.iterdir())  # nothing ran


def test_play_prints_success_only_when_the_video_exists(run_copy, tmp_path, monkeypatch, capsys):
    run_dir, _ = run_copy

    def writes_nothing(*args, **kwargs):  # as ffmpeg failing without an exception
        while True:
            yield

    monkeypatch.setattr(imageio_ffmpeg, "write_frames", writes_nothing)
    out = tmp_path / "play.mp4"
    try:
        status = main(["play", str(run_dir), "--out", str(out), "--seconds", "0.04",
                       "--width", "64", "--height", "48"])
    except RuntimeError as err:
        if "OpenGL" in str(err):
            pytest.skip(f"no OpenGL platform here: {err}")
        raise
    assert status == 2
    assert f"no video was written to {out}" in one_line(capsys, "play")
    assert str(out) not in capsys.readouterr().out
    assert [p.name for p in tmp_path.iterdir()] == ["runs"]  # no temporary left behind either


def test_unwritable_outputs_are_one_line(run_copy, tmp_path, capsys):
    run_dir, root = run_copy
    a_file = tmp_path / "notes.txt"
    a_file.write_text("keep me")
    cases = [(["play", str(run_dir), "--out", str(a_file / "play.mp4")], "--out"),
             (["export", str(run_dir), "--out-dir", str(a_file)], "--out-dir"),
             (["train", "cartpole", "--log-root", str(a_file / "runs")], "--log-root")]
    for argv, flag in cases:
        assert main(argv) == 2
        line = one_line(capsys, argv[0])
        assert flag in line and str(a_file) in line and f"give {flag} a place you can write" in line
    assert a_file.read_text() == "keep me"
    assert sorted(p.name for p in (root / "cartpole").iterdir()) == [run_dir.name]


def test_missing_runs_are_one_line(tmp_path, capsys):
    for command in ("play", "eval", "export"):
        assert main([command, "cartpole", "--log-root", str(tmp_path)]) == 2
        line = one_line(capsys, command)
        assert f"no runs of task 'cartpole' under {tmp_path}/" in line
        assert "train one with `ambulo train cartpole`" in line
    assert main(["train", "cartpole", "--resume", "--log-root", str(tmp_path)]) == 2
    assert "no runs of task 'cartpole'" in one_line(capsys, "train")
