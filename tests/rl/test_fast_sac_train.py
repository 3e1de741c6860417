"""fast-sac and fast-td3 (``ambulo train --algo``) through ambulo's run machinery, on the CPU."""

import csv

import pytest
import torch

from ambulo.rl import evaluate, export, train
from ambulo.rl.runs import checkpoints, read_run_info

SHORT = dict(num_envs=8, max_iterations=4)  # updates start at iteration 2 (learning_starts 16 steps)


def _actor(run_dir, iteration):
    return torch.load(run_dir / f"model_{iteration}.pt", weights_only=False)["model"]


@pytest.mark.parametrize("algo", ["fast-sac", "fast-td3"])
def test_same_seed_same_weights(tmp_path, algo):
    runs = [train("cartpole", algo=algo, seed=seed, log_root=tmp_path / str(i), **SHORT)
            for i, seed in enumerate((3, 3, 4))]
    first, again, other = (_actor(r, 3) for r in runs)
    assert all(torch.equal(first[k], again[k]) for k in first)
    assert not all(torch.equal(first[k], other[k]) for k in first)
    # the updates moved the weights away from the initial ones
    start = _actor(runs[0], 0)
    assert not torch.equal(start["actor.net.0.weight"], first["actor.net.0.weight"])
    info = read_run_info(runs[0])
    assert info["algo"] == algo and info["offpolicy"]["num_envs"] == 8 and "ppo" not in info


def test_resume_continues_the_run_and_its_algorithm(tmp_path):
    run_dir = train("cartpole", algo="fast-td3", seed=0, log_root=tmp_path, **SHORT)
    again = train(resume=run_dir, max_iterations=6)
    assert again == run_dir
    rows = list(csv.DictReader(open(run_dir / "metrics.csv")))
    assert [int(r["iteration"]) for r in rows] == list(range(6))
    assert [it for it, _ in checkpoints(run_dir)] == [0, 3, 5]
    with pytest.raises(ValueError, match="trained with fast-td3"):
        train(resume=run_dir, algo="fast-sac", max_iterations=8)


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["fast-sac", "fast-td3"])  # met at iterations 99 and 124 (12,800 / 16,000 env steps)
def test_balances_cartpole_and_exports(tmp_path, algo):
    """The learner must solve cartpole: the task's criterion (fall rate <= 5 % over 100
    evaluation episodes) from the default settings, and the actor exports like PPO's."""
    run_dir = train("cartpole", algo=algo, seed=0, log_root=tmp_path, eval_every=25,
                    stop_at_criterion=True, max_iterations=200)
    rows = list(csv.DictReader(open(run_dir / "evals.csv")))
    assert rows[-1]["criteria_met"] == "True", rows
    result = evaluate(run_dir, quiet=True)
    assert result["balances"] and result["fall_rate"] <= 0.05
    exported = export(run_dir, out_dir=tmp_path / "exported")
    assert exported["onnx_max_abs_diff"] < 1e-4 and exported["torchscript_max_abs_diff"] < 1e-5


@pytest.mark.slow
def test_balances_cartpole_collecting_beside_the_updates_judged_in_the_background(tmp_path):
    """``overlap_collect`` (the worlds act with an actor one update round old) still solves cartpole,
    and ``eval_async`` stops the run at the worker's first success."""
    run_dir = train("cartpole", algo="fast-sac", seed=0, log_root=tmp_path, eval_every=25, stop_at_criterion=True,
                    max_iterations=300, algo_overrides={"overlap_collect": True}, eval_async=True)
    rows = list(csv.DictReader(open(run_dir / "evals.csv")))
    assert rows[-1]["criteria_met"] == "True", rows
    assert read_run_info(run_dir)["offpolicy"]["overlap_collect"] is True
    assert evaluate(run_dir, checkpoint=f"model_{rows[-1]['iteration']}.pt", quiet=True)["balances"]
