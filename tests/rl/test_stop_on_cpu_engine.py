"""--stop-at-criterion on a GPU: a success there counts only once the CPU engine confirms it.

Training on a GPU is simulated: the evaluation env (the CPU engine here) is declared another
engine and its results are scripted; the CPU-engine confirmation is real (cartpole, 100
episodes on MuJoCo C) with its verdict scripted per confirmation.
"""

import csv
import json

import pytest
import torch

from ambulo.engine import CpuEngine
from ambulo.rl import evaluate, periodic_eval, train
from ambulo.rl.periodic_eval import EVAL_COLUMNS, resume_evals

EVERY = 2
MAIN_PASSES_FROM = 3  # iteration of the first evaluation that meets the criterion on "the GPU"
CPU_PASSES_AT = 3  # the CPU engine confirms only its 3rd success: the one at iteration 7
STOP = 7


@pytest.fixture(scope="module")
def gpu_like_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    real = periodic_eval.run_episodes
    seen = {"evaluations": 0, "confirmations": 0, "cpu_envs": []}
    patch = pytest.MonkeyPatch()

    def scripted(env, vec_env, policy, task, **kwargs):
        if env.cfg.engine != "mujoco":  # the evaluation env: "the GPU engine"
            seen["evaluations"] += 1
            iteration = seen["evaluations"] * EVERY - 1
            met = iteration >= MAIN_PASSES_FROM
            return {"fall_rate": 0.0 if met else 0.5, "mean_episode_length_s": 5.0, "mean_return": 1.0,
                    "criteria": ["balances"], "balances": met}
        seen["confirmations"] += 1
        seen["cpu_envs"].append((type(env.engine), env.num_envs,
                                 {p.device.type for p in policy.parameters()}))
        result = real(env, vec_env, policy, task, **kwargs)
        return {**result, "balances": seen["confirmations"] >= CPU_PASSES_AT}

    patch.setattr(periodic_eval, "run_episodes", scripted)
    patch.setattr(periodic_eval, "is_cpu_engine", lambda env: False)
    try:
        train("cartpole", num_envs=64, max_iterations=40, seed=0, log_root=root, eval_every=EVERY,
              stop_at_criterion=True)
    finally:
        patch.undo()
    return next(root.glob("cartpole/*")), seen


def test_training_goes_on_while_the_cpu_engine_does_not_confirm(gpu_like_run):
    run, seen = gpu_like_run
    rows = list(csv.DictReader(open(run / "evals.csv")))
    assert [int(r["iteration"]) for r in rows] == list(range(EVERY - 1, STOP + 1, EVERY))
    assert [r["criteria_met"] for r in rows] == ["False", "True", "True", "True"]
    assert [r["cpu_engine_criteria_met"] for r in rows] == ["", "False", "False", "True"]
    assert all("fall_rate=" in r["cpu_engine_metrics"] for r in rows[1:])
    metrics = list(csv.DictReader(open(run / "metrics.csv")))
    assert int(metrics[-1]["iteration"]) == STOP, "training stopped before the CPU engine confirmed"
    reached = json.loads((run / "time_to_criterion.json").read_text())
    assert reached["iteration"] == STOP and reached["checkpoint"] == f"model_{STOP}.pt"
    assert reached["eval"]["balances"] and reached["eval_cpu_engine"]["balances"]
    assert reached["wall_s"] == pytest.approx(float(rows[-1]["wall_s"]), abs=0.2)


def test_the_confirmation_runs_the_policy_on_the_cpu_engine(gpu_like_run):
    _, seen = gpu_like_run
    assert seen["confirmations"] == CPU_PASSES_AT  # only successes are confirmed
    assert seen["cpu_envs"] == [(CpuEngine, 100, {"cpu"})] * CPU_PASSES_AT


def test_the_confirmation_is_ambulo_eval_on_the_cpu(gpu_like_run):
    """The CPU-engine numbers recorded are those `ambulo eval RUN --checkpoint ... --device cpu` prints."""
    run, _ = gpu_like_run
    reached = json.loads((run / "time_to_criterion.json").read_text())
    again = evaluate(run, checkpoint=reached["checkpoint"], device="cpu", quiet=True)
    for key in ("fall_rate", "mean_return", "mean_episode_length_s"):
        assert again[key] == reached["eval_cpu_engine"][key], key
    assert torch.device(again["device"]).type == "cpu"


def test_a_resume_keeps_the_rows_of_an_evals_csv_without_the_cpu_engine_columns(tmp_path):
    old = EVAL_COLUMNS[:8]  # evals.csv before the CPU-engine confirmation
    (tmp_path / "evals.csv").write_text(",".join(old) + "\n1,2.0,64,0.500,2.00,1.00,,False\n"
                                        "3,4.0,256,0.000,5.00,9.00,,True\n")
    resume_evals(tmp_path, start=4)
    rows = list(csv.DictReader(open(tmp_path / "evals.csv")))
    assert [r["iteration"] for r in rows] == ["1", "3"] and list(rows[0]) == list(EVAL_COLUMNS)
    assert rows[1]["criteria_met"] == "True" and rows[1]["cpu_engine_criteria_met"] == ""
