"""The worker process of ``eval_async.BackgroundEval`` (``python -m ambulo.rl.eval_worker``).

It reads JSON lines on stdin: first the evaluation's settings (``info``, ``run_dir``,
``num_episodes``, ``seed``, ``device``, ``confirm_on_cpu_engine``), then one ``{"iteration",
"checkpoint"}`` per checkpoint to judge. It builds its ``PeriodicEval`` (recording nothing: the
training process records) at the first checkpoint, so its kernels load from the cache the
training process has filled by then, and answers ``{"ready", ...}`` once. It judges on the CPU
engine first (``PeriodicEval.evaluate(cpu_first=True)``) where a success needs its confirmation:
the evaluation env, which shares the training GPU, runs only for a checkpoint that meets the
criteria there; its threads run at a lower priority (``nice`` 10). For each checkpoint it
answers ``{"iteration", "result", "met", "cpu", "confirmed", "skipped"}``; when several
wait, it judges the newest and lists the others under ``skipped``. Each answer is one line that
starts with ``eval_async.ANSWER``. On an error it answers
``{"error": "Type: message"}`` and exits 1. End of stdin ends it; so does a broken answer pipe
(training killed without closing it: one line in the log, exit 0, no traceback). Anything printed (by ambulo,
MuJoCo or Warp) goes to stderr, the run's ``eval_worker.log``: stdout carries only the answers.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import sys
import threading
import time
from collections import deque
from pathlib import Path

from .eval_async import ANSWER


def _answers():
    """A line writer on the real stdout; fd 1 then points at stderr, so stray prints (Python's or
    a C library's) cannot corrupt the answers."""
    out = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    sys.stdout = sys.stderr

    def answer(message: dict) -> None:
        try:
            out.write(ANSWER + json.dumps(message) + "\n")
        except BrokenPipeError as error:
            # the training process is gone (killed, or ended without closing us): nothing reads the
            # answers; point the fd at /dev/null so the buffer's flush at exit cannot fail again
            os.dup2(os.open(os.devnull, os.O_WRONLY), out.fileno())
            raise TrainingGone from error

    return answer


class TrainingGone(Exception):
    """The pipe to the training process broke: the worker has no one to answer and stops."""


def serve() -> int:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # training's Ctrl-C is training's to handle
    os.nice(10)  # the CPU-engine evaluation's threads yield to training's host thread
    answer = _answers()
    jobs: deque = deque()
    arrived = threading.Condition()
    done = []

    def read() -> None:
        for line in sys.stdin:
            with arrived:
                jobs.append(json.loads(line))
                arrived.notify()
        with arrived:
            done.append(True)
            arrived.notify()

    def take(wait: bool = True) -> list[dict]:
        """Every message arrived so far (waiting for one when ``wait``); [] once stdin ended."""
        with arrived:
            while wait and not jobs and not done:
                arrived.wait()
            taken = list(jobs)
            jobs.clear()
            return taken

    threading.Thread(target=read, daemon=True).start()
    try:
        waiting = take()
        if not waiting:
            return 0
        settings, waiting, periodic = waiting[0], waiting[1:], None
        while True:
            waiting = waiting or take()
            if not waiting:
                return 0
            if periodic is None:
                periodic = _evaluator(settings)
                answer({"ready": True, "confirm": periodic.confirm, "on_cpu_engine": periodic.on_cpu_engine,
                        "eval_device": periodic.eval_device})
                waiting += take(wait=False)  # checkpoints saved while the env was built: judge the newest
            newest = waiting[-1]
            result, met, cpu, confirmed = _judge(periodic, settings, Path(newest["checkpoint"]))
            answer({"iteration": newest["iteration"], "result": result, "met": met, "cpu": cpu,
                    "confirmed": confirmed, "skipped": [job["iteration"] for job in waiting[:-1]]})
            waiting = []
    except TrainingGone:
        print("the training process is gone (its pipe broke); the worker stops", file=sys.stderr)
        return 0
    except Exception as error:  # the training process reports it and stops
        import traceback

        traceback.print_exc()
        first = (str(error).strip().splitlines() or [""])[0][:300]
        with contextlib.suppress(TrainingGone):  # no one left to tell: the traceback above is in the log
            answer({"error": f"{type(error).__name__}: {first}"})
        return 1


def _evaluator(settings: dict):
    from .periodic_eval import PeriodicEval

    return PeriodicEval(settings["info"], Path(settings["run_dir"]), every=1, started_s=time.monotonic(),
                        steps_per_iteration=1, num_episodes=settings["num_episodes"], seed=settings["seed"],
                        device=settings["device"], confirm_on_cpu_engine=settings["confirm_on_cpu_engine"],
                        records=False)


def _judge(periodic, settings: dict, checkpoint: Path):
    """``checkpoint``'s deterministic policy through ``periodic.evaluate``."""
    from . import runs

    runner = runs.load_runner(Path(settings["run_dir"]), periodic.env, checkpoint)
    # the CPU engine first: most checkpoints fail there, and the GPU stays training's
    return periodic.evaluate(runner.get_inference_policy(device=str(periodic.env.device)), cpu_first=True)


if __name__ == "__main__":
    sys.exit(serve())
