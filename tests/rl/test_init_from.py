"""``ambulo train TASK --init-from CHECKPOINT_OR_RUN``: a new run whose networks start from a trained
policy's weights, with its own settings, a fresh optimizer and iteration 0; refusals in one line."""

import csv
import json

import pytest
import torch

from ambulo.cli import main
from ambulo.rl import train
from ambulo.rl.offpolicy.runner import OffPolicyRunner
from ambulo.rl.runs import checkpoints, read_run_info
from ambulo.rl.train import AmbuloRunner

FAST = ["--num-envs", "8", "--ppo-cfg", "num_steps_per_env=8", "--ppo-cfg", "save_interval=1"]


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """A cartpole PPO run of 2 iterations (model_0.pt, model_1.pt) and a fast-sac one."""
    root = tmp_path_factory.mktemp("source")
    ppo = train("cartpole", num_envs=8, max_iterations=2, log_root=root / "ppo",
                ppo_overrides={"num_steps_per_env": 8, "save_interval": 1})
    sac = train("cartpole", algo="fast-sac", num_envs=8, max_iterations=3, log_root=root / "sac")
    return ppo, sac


def loaded_state(monkeypatch, runner_class):
    """What ``runner_class.load_for_init`` left in the runner: filled in when the run loads."""
    seen = {}
    load = runner_class.load_for_init

    def recording(self, path, task):
        load(self, path, task)
        if runner_class is AmbuloRunner:
            seen["weights"] = {k: {n: t.clone() for n, t in v.items()} for k, v in self.alg.save().items()
                               if k.endswith("_state_dict") and k != "optimizer_state_dict"}
            seen["optimizers"] = [self.alg.optimizer.state_dict()]
        else:
            seen["weights"] = {"model": {n: t.clone() for n, t in self.alg.state_dict().items()}}
            seen["optimizers"] = [self.alg.actor_opt.state_dict(), self.alg.critic_opt.state_dict()]
            seen["num_updates"] = self.alg.num_updates
        seen["iteration"] = self.current_learning_iteration

    monkeypatch.setattr(runner_class, "load_for_init", recording)
    return seen


def new_runs(root, before):
    return sorted(p for p in (root / "cartpole").iterdir() if p not in before)


def test_a_new_run_starts_from_the_weights_with_its_own_settings(source, tmp_path, monkeypatch, capsys):
    src, _ = source
    root = src.parents[1]
    before = set((root / "cartpole").iterdir())
    seen = loaded_state(monkeypatch, AmbuloRunner)
    assert main(["train", "cartpole", "--init-from", str(src), "--max-iterations", "2", *FAST,
                 "--env-cfg", "initial_pole_angle_rad=0.1", "--ppo-cfg", "learning_rate=3e-4",
                 "--log-root", str(root)]) == 0
    [run] = new_runs(root, before)
    assert run != src
    # the newest readable checkpoint of the folder, loaded exactly: actor, critic, normalizers
    saved = torch.load(src / "model_1.pt", weights_only=False)
    for net in ("actor_state_dict", "critic_state_dict"):
        assert seen["weights"][net].keys() == saved[net].keys()
        assert any("normalizer" in name for name in saved[net])
        for name, tensor in saved[net].items():
            assert torch.equal(seen["weights"][net][name], tensor), (net, name)
    assert seen["iteration"] == 0
    info = read_run_info(run)
    assert info["init_from"] == str((src / "model_1.pt").resolve())
    assert info["env_overrides"] == {"initial_pole_angle_rad": 0.1} and info["ppo"]["learning_rate"] == 3e-4
    assert [it for it, _ in checkpoints(run)] == [0, 1]
    assert [int(r["iteration"]) for r in csv.DictReader(open(run / "metrics.csv"))] == [0, 1]
    assert "from the weights of" in capsys.readouterr().out


def test_the_optimizer_starts_fresh(source, tmp_path, monkeypatch):
    src, _ = source
    assert torch.load(src / "model_1.pt", weights_only=False)["optimizer_state_dict"]["state"]  # Adam has stepped
    seen = loaded_state(monkeypatch, AmbuloRunner)
    run = train("cartpole", init_from=src / "model_0.pt", num_envs=8, max_iterations=1, log_root=tmp_path,
                ppo_overrides={"num_steps_per_env": 8, "learning_rate": 2e-4})
    [optimizer] = seen["optimizers"]
    assert optimizer["state"] == {}  # no step count, no exp_avg
    assert optimizer["param_groups"][0]["lr"] == 2e-4  # this run's rate, not the old run's last
    assert read_run_info(run)["init_from"] == str((src / "model_0.pt").resolve())


def test_off_policy_loads_the_networks_not_the_optimizers(source, tmp_path, monkeypatch):
    _, src = source
    seen = loaded_state(monkeypatch, OffPolicyRunner)
    run = train("cartpole", algo="fast-sac", init_from=src, num_envs=8, max_iterations=1, log_root=tmp_path)
    [checkpoint] = [p for it, p in checkpoints(src) if it == 2]
    saved = torch.load(checkpoint, weights_only=False)
    assert saved["num_updates"] > 0 and saved["actor_opt"]["state"]
    for name, tensor in saved["model"].items():
        assert torch.equal(seen["weights"]["model"][name], tensor), name
    assert all(opt["state"] == {} for opt in seen["optimizers"]) and seen["num_updates"] == 0
    assert seen["iteration"] == 0
    assert read_run_info(run)["init_from"] == str(checkpoint.resolve())


def one_line_refusal(capsys, argv):
    status = main(["train", "cartpole", *argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and err[0].startswith("ambulo train: error: "), err
    return err[0]


def test_refusals_are_one_line_and_leave_no_run(source, tmp_path, capsys):
    ppo, sac = source
    log_root = tmp_path / "runs"
    empty = tmp_path / "empty"
    empty.mkdir()
    (tmp_path / "notes.pt").write_text("not a checkpoint")
    cases = [
        (["--init-from", str(ppo), "--resume"], ["--init-from and --resume both given", "give one of them"]),
        (["--init-from", str(tmp_path / "nothing")], ["no such checkpoint file or run folder", "model_<iteration>.pt"]),
        (["--init-from", str(empty)], ["cannot init from", "has no checkpoint"]),
        (["--init-from", str(tmp_path / "notes.pt")], ["cannot init from", "unreadable"]),
        (["--init-from", "shipped"], ["shipped policy keeps only its exported actor"]),
        (["--init-from", str(ppo), "--ppo-cfg", "actor_hidden_dims=16,16"],
         ["do not match task cartpole's", "actor.mlp.0.weight is 32x4 in it, 16x4 here", "hidden sizes"]),
        (["--init-from", str(sac), "--algo", "fast-sac", "--algo-cfg", "critic_hidden_dims=16,16"],
         ["do not match task cartpole's", "model.critic.q1.0.weight is 64x5 in it, 16x5 here", "--algo-cfg"]),
        (["--init-from", str(sac)], ["cannot init a ppo run from", "fast-sac trained it", "add --algo fast-sac"]),
        (["--init-from", str(ppo), "--algo", "fast-td3"], ["cannot init a fast-td3 run", "ppo trained it"]),
    ]
    for argv, needles in cases:
        line = one_line_refusal(capsys, [*argv, *FAST[:2], "--max-iterations", "1", "--log-root", str(log_root)])
        for needle in needles:
            assert needle in line, line
        assert not log_root.exists() or not list(log_root.iterdir()), (argv, list(log_root.rglob("*")))


def test_the_source_run_json_names_the_algorithm(source, tmp_path, capsys):
    """A checkpoint copied out of its run folder still says which algorithm wrote it."""
    _, sac = source
    lone = tmp_path / "model_2.pt"
    lone.write_bytes((sac / "model_2.pt").read_bytes())
    line = one_line_refusal(capsys, ["--init-from", str(lone), "--max-iterations", "1",
                                     "--log-root", str(tmp_path / "runs")])
    assert "fast-sac trained it" in line
    assert json.loads((sac / "run.json").read_text())["algo"] == "fast-sac"
