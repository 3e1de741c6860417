"""--eval-every: the policy under training is evaluated as `ambulo eval` does and the first
success is timed; --stop-at-criterion ends training there."""

import csv
import json

import pytest

from ambulo.cli import main
from ambulo.rl import evaluate
from ambulo.rl.runs import checkpoints


@pytest.fixture(scope="module")
def timed_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    status = main(["train", "cartpole", "--num-envs", "256", "--max-iterations", "200", "--seed", "0",
                   "--eval-every", "10", "--stop-at-criterion", "--log-root", str(root)])
    assert status == 0
    return next(root.glob("cartpole/*"))


def test_training_stops_at_the_first_evaluation_that_balances(timed_run):
    rows = list(csv.DictReader(open(timed_run / "evals.csv")))
    met = [r["criteria_met"] == "True" for r in rows]
    assert met[-1] and not any(met[:-1]), "training went on past the first success or stopped early"
    last = int(rows[-1]["iteration"])
    assert last < 199 and (last + 1) % 10 == 0
    metrics = list(csv.DictReader(open(timed_run / "metrics.csv")))
    assert int(metrics[-1]["iteration"]) == last  # no iteration after the successful evaluation
    reached = json.loads((timed_run / "time_to_criterion.json").read_text())
    assert reached["iteration"] == last and reached["checkpoint"] == f"model_{last}.pt"
    assert reached["env_steps"] == (last + 1) * 256 * 32  # cartpole's 32-step rollouts
    assert 0 < reached["eval_s_included"] < reached["wall_s"]
    assert [int(r["iteration"]) for r in rows] == list(range(9, last + 1, 10))
    walls = [float(r["wall_s"]) for r in rows]
    assert walls == sorted(walls) and reached["wall_s"] == pytest.approx(walls[-1], abs=0.2)


def test_the_timed_checkpoint_passes_ambulo_eval(timed_run):
    """The checkpoint judged during training is saved and `ambulo eval` gives the same numbers: the
    periodic evaluation runs the episodes `ambulo eval` runs for that seed and device."""
    reached = json.loads((timed_run / "time_to_criterion.json").read_text())
    assert reached["checkpoint"] in [path.name for _, path in checkpoints(timed_run)]
    again = evaluate(timed_run, checkpoint=reached["checkpoint"], quiet=True)
    assert again["balances"] is True
    for key in ("fall_rate", "mean_return", "mean_episode_length_s"):
        assert again[key] == reached["eval"][key], key
    assert reached["eval_cpu_engine"] == reached["eval"]  # trained on the CPU engine: nothing to confirm


def test_stop_at_criterion_needs_eval_every(tmp_path, capsys):
    assert main(["train", "cartpole", "--stop-at-criterion", "--log-root", str(tmp_path)]) == 2
    assert "--stop-at-criterion needs --eval-every" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())
