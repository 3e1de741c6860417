"""--eval-async: a worker process judges the checkpoints while training goes on, exactly as the
synchronous evaluation would, and the training process records what it finds."""

import csv
import json
import queue
import shutil
import subprocess
import sys
import time
from types import SimpleNamespace

import pytest

from ambulo.cli import main
from ambulo.rl import evaluate
from ambulo.rl.eval_async import ANSWER, WORKER_LOG, BackgroundEval
from ambulo.rl.runs import read_run_info


@pytest.fixture(scope="module")
def async_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    status = main(["train", "cartpole", "--num-envs", "256", "--max-iterations", "200", "--seed", "0",
                   "--eval-every", "10", "--stop-at-criterion", "--eval-async", "--log-root", str(root)])
    assert status == 0
    return next(root.glob("cartpole/*"))


def test_training_stops_once_the_worker_finds_the_criterion_met(async_run):
    rows = list(csv.DictReader(open(async_run / "evals.csv")))
    met = [r["criteria_met"] == "True" for r in rows]
    assert met[-1] and not any(met[:-1])
    iterations = [int(r["iteration"]) for r in rows]
    assert iterations == sorted(iterations) and all((i + 1) % 10 == 0 for i in iterations)
    reached = json.loads((async_run / "time_to_criterion.json").read_text())
    last = iterations[-1]
    assert reached["iteration"] == last and reached["checkpoint"] == f"model_{last}.pt" and reached["eval_async"]
    # the verdict comes after the checkpoint; training went on meanwhile, but stopped
    assert reached["checkpoint_wall_s"] <= reached["wall_s"]
    trained = int(list(csv.DictReader(open(async_run / "metrics.csv")))[-1]["iteration"])
    assert last <= trained < 199
    assert reached["eval_s_included"] < 0.5 * reached["wall_s"]  # the trainer only saved and handed over


def test_the_worker_judges_as_ambulo_eval_does(async_run):
    """Its numbers are `ambulo eval`'s for the same checkpoint and seed: the same episodes."""
    reached = json.loads((async_run / "time_to_criterion.json").read_text())
    again = evaluate(async_run, checkpoint=reached["checkpoint"], quiet=True)
    for key in ("fall_rate", "mean_return", "mean_episode_length_s", "balances"):
        assert again[key] == reached["eval"][key], key
    first = list(csv.DictReader(open(async_run / "evals.csv")))[0]
    early = evaluate(async_run, checkpoint=f"model_{first['iteration']}.pt", quiet=True)
    assert f"{early['mean_return']:.2f}" == first["mean_return"]


class _Saver:
    """A runner stand-in whose checkpoints are copies of a file (or garbage)."""

    logger = None

    def __init__(self, source=None):
        self.source = source

    def save(self, path):
        if self.source is None:
            open(path, "wb").write(b"not a checkpoint")
        else:
            shutil.copy(self.source, path)


def _copy_run(async_run, tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    shutil.copy(async_run / "run.json", run / "run.json")
    return run


def test_the_newest_waiting_checkpoint_is_judged_and_older_ones_skipped(async_run, tmp_path):
    run = _copy_run(async_run, tmp_path)
    reached = json.loads((async_run / "time_to_criterion.json").read_text())
    periodic = BackgroundEval(read_run_info(run), run, every=10, started_s=time.monotonic(), steps_per_iteration=1)
    saver = _Saver(async_run / reached["checkpoint"])
    periodic(saver, 9)
    periodic(saver, 19)  # handed over while the worker still builds its env
    try:
        finished = periodic.poll(block=True, timeout_s=120)
    finally:
        periodic.close()
    assert [it for it, _, _ in finished] == [19] and periodic.skipped == [9]
    rows = list(csv.DictReader(open(run / "evals.csv")))
    assert [r["iteration"] for r in rows] == ["19"] and rows[0]["criteria_met"] == "True"


def test_a_failing_worker_ends_training_with_its_error(async_run, tmp_path):
    run = _copy_run(async_run, tmp_path)
    periodic = BackgroundEval(read_run_info(run), run, every=10, started_s=time.monotonic(), steps_per_iteration=1)
    periodic(_Saver(), 9)
    with pytest.raises(RuntimeError, match=r"the background evaluation failed \(\w+Error: .*drop --eval-async"):
        periodic.poll(block=True, timeout_s=120)
    periodic.close()
    assert "Traceback" in (run / WORKER_LOG).read_text()
    assert not (run / "time_to_criterion.json").exists()


def test_eval_async_needs_eval_every(tmp_path, capsys):
    assert main(["train", "cartpole", "--eval-async", "--log-root", str(tmp_path)]) == 2
    assert "--eval-async needs --eval-every" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


def test_an_off_policy_run_records_the_evaluations_still_running_when_it_ends(tmp_path):
    """Training ends (its iterations done) with evaluations under way: they are waited for and
    recorded; the worker loads fast-sac's actor as `ambulo eval` does."""
    assert main(["train", "cartpole", "--algo", "fast-sac", "--max-iterations", "10", "--seed", "0",
                 "--eval-every", "5", "--eval-async", "--log-root", str(tmp_path)]) == 0
    run = next(tmp_path.glob("cartpole/*"))
    rows = list(csv.DictReader(open(run / "evals.csv")))
    assert [r["iteration"] for r in rows][-1] == "9"
    again = evaluate(run, checkpoint="model_9.pt", quiet=True)
    assert f"{again['mean_return']:.2f}" == rows[-1]["mean_return"]


def test_a_stopped_run_does_not_wait_for_the_evaluation_under_way(async_run, tmp_path):
    """Ctrl-C, the criterion or an error end training at once: ``close`` ends the worker without
    recording what it had not finished (``finish``, after the last iteration, waits)."""
    run = _copy_run(async_run, tmp_path)
    reached = json.loads((async_run / "time_to_criterion.json").read_text())
    periodic = BackgroundEval(read_run_info(run), run, every=10, started_s=time.monotonic(), steps_per_iteration=1)
    periodic(_Saver(async_run / reached["checkpoint"]), 9)
    periodic.close()
    assert periodic._proc.poll() is not None
    assert list(csv.DictReader(open(run / "evals.csv"))) == [] and periodic.pending


def test_lines_that_are_not_answers_go_to_the_log(tmp_path):
    """A library may print to stdout while the worker imports ambulo, before it points fd 1 at its log."""
    periodic = BackgroundEval.__new__(BackgroundEval)  # the reader alone, on scripted output
    periodic._proc = SimpleNamespace(stdout=[b"Warp 1.19.0 initialized\n", (ANSWER + '{"ready": true}\n').encode()])
    periodic._log, periodic._replies = open(tmp_path / "log", "ab"), queue.Queue()
    periodic._read()
    periodic._log.close()
    assert periodic._replies.get_nowait() == {"ready": True} and periodic._replies.get_nowait() is None
    assert (tmp_path / "log").read_bytes() == b"Warp 1.19.0 initialized\n"


@pytest.mark.parametrize("broken", [False, True])
def test_the_worker_stops_quietly_once_training_is_gone(async_run, tmp_path, broken):
    """Training killed (its end of the answer pipe closed, stdin left open): the worker's next answer
    finds no reader; it logs one line and exits 0, without a traceback. A worker that fails before
    its first answer (settings naming no task) leaves that error's traceback and exit status 1, not a
    second one for the broken pipe it reports the error to."""
    run = _copy_run(async_run, tmp_path)
    reached = json.loads((async_run / "time_to_criterion.json").read_text())
    shutil.copy(async_run / reached["checkpoint"], run / "model_9.pt")
    info = read_run_info(run)
    if broken:
        info = {**info, "task": "no-such-task"}
    log = open(tmp_path / "worker.log", "wb")
    proc = subprocess.Popen([sys.executable, "-m", "ambulo.rl.eval_worker"], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=log)
    proc.stdout.close()  # nothing will read the answers
    for message in ({"info": info, "run_dir": str(run), "num_episodes": 8, "seed": 0, "device": "cpu",
                     "confirm_on_cpu_engine": True}, {"iteration": 9, "checkpoint": str(run / "model_9.pt")}):
        proc.stdin.write((json.dumps(message) + "\n").encode())
    proc.stdin.flush()
    try:
        assert proc.wait(timeout=120) == (1 if broken else 0)
    finally:
        proc.kill()
        proc.stdin.close()
        log.close()
    text = (tmp_path / "worker.log").read_text()
    assert "BrokenPipeError" not in text and "TrainingGone" not in text
    if broken:
        assert text.count("Traceback") == 1 and "no-such-task" in text
    else:
        assert "the training process is gone" in text and "Traceback" not in text and "Exception" not in text


def test_the_worker_judges_on_the_cpu_engine_first(async_run, tmp_path):
    """A success off the CPU engine needs both engines: the worker judges the CPU engine first and
    runs the evaluation env only for a policy that meets the criteria there, so a failing one
    (most of them) leaves the GPU to training. Here the evaluation env is MuJoCo C too, told to
    confirm as a GPU run's would."""
    from ambulo.rl.eval_worker import _judge
    from ambulo.rl.periodic_eval import PeriodicEval

    run = _copy_run(async_run, tmp_path)
    # the first checkpoint (saved even if the worker skipped it) fails; the last met the criteria
    first, last = "9", list(csv.DictReader(open(async_run / "evals.csv")))[-1]["iteration"]
    for it in (first, last):
        shutil.copy(async_run / f"model_{it}.pt", run / f"model_{it}.pt")
    periodic = PeriodicEval(read_run_info(run), run, every=1, started_s=time.monotonic(), steps_per_iteration=1)
    periodic.confirm = True  # as off the CPU engine
    runs_of_eval_env = []
    run_eval_env = periodic._run
    periodic._run = lambda policy: runs_of_eval_env.append(1) or run_eval_env(policy)
    settings = {"run_dir": str(run)}

    result, met, cpu, confirmed = _judge(periodic, settings, run / f"model_{first}.pt")
    assert (result["eval_engine"], met, cpu, confirmed) == ("cpu", False, None, False) and not runs_of_eval_env
    again = evaluate(run, checkpoint=f"model_{first}.pt", device="cpu", quiet=True)  # the CPU engine's numbers
    assert result["mean_return"] == again["mean_return"] and result["fall_rate"] == again["fall_rate"]
    periodic._record(SimpleNamespace(logger=None), int(first), run / f"model_{first}.pt", 1.0, result, met, cpu,
                     confirmed)

    result, met, cpu, confirmed = _judge(periodic, settings, run / f"model_{last}.pt")
    assert met and confirmed and cpu is not None and result["cpu_engine"] == cpu and len(runs_of_eval_env) == 1
    assert "eval_engine" not in result
    periodic._record(SimpleNamespace(logger=None), int(last), run / f"model_{last}.pt", 2.0, result, met, cpu,
                     confirmed)
    periodic.close()
    written = list(csv.DictReader(open(run / "evals.csv")))
    assert [r["eval_engine"] for r in written] == ["cpu", "training"]
    assert written[0]["criteria_met"] == "False" and written[0]["cpu_engine_metrics"] == ""
    assert written[1]["cpu_engine_criteria_met"] == "True"
    assert json.loads((run / "time_to_criterion.json").read_text())["iteration"] == int(last)


@pytest.mark.slow
def test_a_success_off_the_cpu_engine_is_confirmed_on_it_by_the_worker(tmp_path):
    """MuJoCo Warp (on the CPU here, as a GPU run would): the worker's success counts once its
    CPU-engine confirmation holds, and the record says both."""
    assert main(["train", "cartpole", "--num-envs", "64", "--max-iterations", "60", "--seed", "0", "--env-cfg",
                 "engine=warp", "--eval-every", "10", "--stop-at-criterion", "--eval-async",
                 "--log-root", str(tmp_path)]) == 0
    run = next(tmp_path.glob("cartpole/*"))
    rows = list(csv.DictReader(open(run / "evals.csv")))
    assert rows[-1]["criteria_met"] == "True" and rows[-1]["cpu_engine_criteria_met"] == "True"
    assert all(r["cpu_engine_metrics"] == "" for r in rows[:-1])  # confirmed only what met the criteria
    reached = json.loads((run / "time_to_criterion.json").read_text())
    assert reached["eval_async"] and reached["eval_cpu_engine"]["balances"] is True
