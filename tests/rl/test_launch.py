"""`ambulo train --num-gpus N`: the same command as N torchrun ranks, started by ambulo."""

import json

import pytest

from ambulo.cli import main
from ambulo.rl import launch


def test_without_option_drops_the_option_and_its_value_in_both_spellings():
    argv = ["train", "cartpole", "--num-gpus", "2", "--seed", "3", "--num-gpus=4", "--num-envs", "8"]
    assert launch.without_option(argv, "--num-gpus") == ["train", "cartpole", "--seed", "3", "--num-envs", "8"]


def test_the_cli_hands_the_command_less_the_flag_to_the_ranks(monkeypatch, capsys):
    seen = {}
    monkeypatch.setattr("ambulo.rl.eval_gpus.check_num_gpus",
                        lambda n, device, what: seen.update(checked=(n, device, what)))
    monkeypatch.setattr(launch, "launch_ranks", lambda argv, n: seen.update(argv=argv, n=n) or 0)
    monkeypatch.delenv("LOCAL_RANK", raising=False)
    assert main(["train", "cartpole", "--num-gpus", "2", "--max-iterations", "3"]) == 0
    # no --device given: --num-gpus means the GPUs, and every rank is told so
    assert seen == {"checked": (2, "cuda", "trains"), "n": 2,
                    "argv": ["train", "cartpole", "--max-iterations", "3", "--device", "cuda"]}


def test_a_rank_does_not_launch_again(monkeypatch):
    # under torchrun (LOCAL_RANK set) the command trains; it must not start N more ranks each
    monkeypatch.setenv("LOCAL_RANK", "0")
    monkeypatch.setattr(launch, "launch_ranks", lambda argv, n: pytest.fail("a rank launched ranks"))
    called = {}
    monkeypatch.setattr("ambulo.rl.train", lambda *a, **k: called.update(k))
    assert main(["train", "cartpole", "--num-gpus", "2", "--max-iterations", "1"]) == 0
    assert called["max_iterations"] == 1


@pytest.mark.parametrize("argv, needle", [
    (["--device", "cpu"], "--num-gpus trains on GPUs, but the device is 'cpu'"),
    ([], "GPUs visible"),  # this machine has none
])
def test_num_gpus_without_the_gpus_is_one_line(argv, needle, capsys, monkeypatch):
    monkeypatch.delenv("LOCAL_RANK", raising=False)
    assert main(["train", "cartpole", "--num-gpus", "2", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and len(err.splitlines()) == 1


def test_two_cpu_ranks_started_by_the_launcher_train_one_run(tmp_path):
    # the launcher's own command, on CPU ranks over gloo (the GPU path differs only in the device)
    status = launch.launch_ranks(["train", "cartpole", "--num-envs", "32", "--max-iterations", "2",
                                  "--log-root", str(tmp_path)], 2, env={"OMP_NUM_THREADS": "1"})
    assert status == 0
    (run,) = (tmp_path / "cartpole").iterdir()
    assert json.loads((run / "run.json").read_text())["world_size"] == 2
