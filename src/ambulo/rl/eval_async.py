"""``ambulo train --eval-every K --eval-async``: the periodic evaluations run in a worker process
while training goes on.

A synchronous evaluation (``periodic_eval.PeriodicEval``) pauses training: on an H200 each of
FastSAC's humanoid-walk evaluations (100 episodes of 20 s) took ~3.6 s against 7 s for the 50
iterations between them, and a rough-terrain one ~8 s against ~17 s for 100 iterations (session
23). Here the training process only saves ``model_<it>.pt`` and hands its path to a worker
(``eval_worker``, started here with the same interpreter and environment), which evaluates it
to the same verdict as the synchronous evaluation (the same ``PeriodicEval.evaluate``: episodes,
seed, both engines) on its own env, on the training device. Where a success needs the CPU
engine's confirmation (a GPU run) it judges the CPU engine first and runs its GPU env only for a
checkpoint that meets the criteria there: on an H200 its GPU evaluations slowed FastSAC's rough
iterations (0.178 s with one every 100 iterations, 0.219 s every 50; session 24), and most
checkpoints fail. Such a row holds the CPU engine's numbers (``evals.csv``'s ``eval_engine``:
``cpu``). The training process records
each result when it arrives, at the end of an iteration: the ``evals.csv`` row, TensorBoard and,
at the first success, ``time_to_criterion.json``, whose ``wall_s`` is the time the verdict was
known (what ``--stop-at-criterion`` stops at), beside ``checkpoint_wall_s``, when the judged
checkpoint was saved. Training may have gone on a few iterations past the judged checkpoint;
the record names it.

If checkpoints come faster than the worker evaluates, it judges the newest waiting one and skips
the older ones (no row): the verdict stays at most one evaluation behind training. A worker
that fails ends training with its error in one line (its log: ``<run>/eval_worker.log``). The
worker has its own session, so the terminal's Ctrl-C reaches training only (which saves, as
always); the worker ends when training closes its pipe. One process only: a data-parallel run
evaluates across its ranks instead.
"""

from __future__ import annotations

import json
import os
import queue
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from .periodic_eval import PeriodicEval

WORKER_LOG = "eval_worker.log"
ANSWER = "ambulo-eval "
"""What starts each of the worker's answers on its stdout; other lines (a library printing while
ambulo is imported, before the worker points fd 1 at its log) go to the log."""


class BackgroundEval(PeriodicEval):
    """``PeriodicEval`` whose evaluations a worker process runs (see the module docstring);
    ``__call__`` saves and hands over (returns None), ``poll`` records what finished."""

    def __init__(self, info: dict[str, Any], run_dir: Path, *, every: int, started_s: float,
                 steps_per_iteration: int, num_episodes: int | None = None, seed: int = 12345,
                 device: str | None = None, start: int = 0, confirm_on_cpu_engine: bool = True,
                 close_timeout_s: float = 600.0):
        """Arguments as ``PeriodicEval``'s (one process: no ``rank``)."""
        super().__init__(info, run_dir, every=every, started_s=started_s, steps_per_iteration=steps_per_iteration,
                         num_episodes=num_episodes, seed=seed, device=device, start=start,
                         confirm_on_cpu_engine=confirm_on_cpu_engine, build_env=False)
        self.close_timeout_s = close_timeout_s
        """How long ``finish`` waits for the evaluations still running when training ends."""
        self.pending: dict[int, tuple[Path, float]] = {}
        """Handed-over iterations not yet judged: their checkpoint and the wall s it was saved at."""
        self.skipped: list[int] = []
        """Iterations the worker skipped for a newer checkpoint."""
        self._runner = None
        self._judged_saved_s = float("nan")
        self._log = open(self.run_dir / WORKER_LOG, "ab")
        import ambulo

        source = str(Path(ambulo.__file__).resolve().parent.parent)  # this ambulo, however it was found
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (source, os.environ.get("PYTHONPATH")) if p)}
        self._proc = subprocess.Popen([sys.executable, "-m", "ambulo.rl.eval_worker"], stdin=subprocess.PIPE,
                                      stdout=subprocess.PIPE, stderr=self._log, env=env, start_new_session=True)
        self._send({"info": info, "run_dir": str(self.run_dir), "num_episodes": num_episodes, "seed": seed,
                    "device": device, "confirm_on_cpu_engine": confirm_on_cpu_engine})
        self._replies: queue.Queue = queue.Queue()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _send(self, message: dict[str, Any]) -> None:
        try:
            self._proc.stdin.write((json.dumps(message) + "\n").encode())
            self._proc.stdin.flush()
        except (BrokenPipeError, OSError):
            self._raise_failure()

    def _read(self) -> None:
        for line in self._proc.stdout:
            text = line.decode(errors="replace")
            if text.startswith(ANSWER):
                self._replies.put(json.loads(text[len(ANSWER):]))
            else:
                try:
                    self._log.write(line)
                except ValueError:  # the log closed as the worker ended
                    pass
        self._replies.put(None)  # the worker's end

    def __call__(self, runner, iteration: int) -> None:
        """Save ``model_<iteration>.pt`` and hand it to the worker; the result comes by ``poll``."""
        began = time.monotonic()
        checkpoint = self.run_dir / f"model_{iteration}.pt"
        runner.save(str(checkpoint))
        self._runner = runner  # its TensorBoard writer records the results
        self.pending[iteration] = (checkpoint, time.monotonic() - self.started_s)
        self._send({"iteration": iteration, "checkpoint": str(checkpoint)})
        self.eval_s += time.monotonic() - began
        return None

    def poll(self, block: bool = False, timeout_s: float | None = None) -> list[tuple[int, dict[str, Any], float]]:
        """Record the evaluations the worker finished; return them as (iteration, result, wall s
        when recorded). ``block``: wait (up to ``timeout_s``) until none is pending."""
        finished = []
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            wait = block and self.pending
            try:
                left = None if deadline is None else max(deadline - time.monotonic(), 0.0)
                reply = self._replies.get(timeout=left) if wait else self._replies.get_nowait()
            except queue.Empty:
                return finished
            if reply is None:
                self._raise_failure()
            if "ready" in reply:  # the worker built its env: what it confirms on
                self.confirm, self.on_cpu_engine = reply["confirm"], reply["on_cpu_engine"]
                self.eval_device = reply["eval_device"]
                continue
            if "error" in reply:
                self._raise_failure(reply["error"])
            finished.append(self._recorded(reply))

    def _recorded(self, reply: dict[str, Any]) -> tuple[int, dict[str, Any], float]:
        iteration = reply["iteration"]
        for old in reply["skipped"]:
            self.pending.pop(old, None)
            self.skipped.append(old)
        checkpoint, self._judged_saved_s = self.pending.pop(iteration)
        wall_s = time.monotonic() - self.started_s
        self._record(self._runner, iteration, checkpoint, wall_s, reply["result"], reply["met"], reply["cpu"],
                     reply["confirmed"])
        return iteration, reply["result"], wall_s

    def _reached_extras(self, iteration: int) -> dict[str, Any]:
        """``time_to_criterion.json``: evaluated in the background, and when the judged checkpoint
        was saved (``wall_s`` is when its verdict was known)."""
        return {"eval_async": True, "checkpoint_wall_s": round(self._judged_saved_s, 1),
                "evaluations_skipped": len(self.skipped)}

    def _raise_failure(self, error: str | None = None) -> None:
        """The worker failed: end training with its error in one line."""
        if error is None:
            try:
                self._proc.wait(timeout=30)
                error = f"it exited with status {self._proc.returncode}"
            except subprocess.TimeoutExpired:
                error = "its answers stopped"
        self._stop()
        raise RuntimeError(f"the background evaluation failed ({error}; log: {self.run_dir / WORKER_LOG}); "
                           "train with evaluations in the training process: drop --eval-async")

    def finish(self) -> None:
        """Training ran all its iterations: wait for the evaluations still running (up to
        ``close_timeout_s``) and record them."""
        if self.reached is None and self.pending and self._proc.poll() is None:
            self.poll(block=True, timeout_s=self.close_timeout_s)

    def close(self) -> None:
        """End the worker, without waiting for an evaluation under way (training stopped: at the
        criterion, interrupted, or failed; ``finish`` waited when it ran to its end)."""
        self._stop()

    def _stop(self) -> None:
        if self._proc.poll() is None:
            self._proc.kill()
            self._proc.wait()
        try:
            self._proc.stdin.close()
        except OSError:  # its pipe broke with the worker
            pass
        self._log.close()


def check_eval_args(eval_every: int | None, stop_at_criterion: bool, eval_async: bool) -> None:
    """ValueError in one line for evaluation flags that need ``eval_every``."""
    if stop_at_criterion and not eval_every:
        raise ValueError("stopping at the criterion needs periodic evaluation; give eval_every too")
    if eval_async and not eval_every:
        raise ValueError("evaluating in the background needs periodic evaluation; give eval_every too")


def make_periodic_eval(info: dict[str, Any], run_dir: Path, *, eval_async: bool = False, **kwargs: Any) -> PeriodicEval:
    """The run's periodic evaluation: in the training process, or (``eval_async``) in a worker."""
    if eval_async:
        kwargs.pop("rank", None)  # one process (checked before)
        return BackgroundEval(info, run_dir, **kwargs)
    return PeriodicEval(info, run_dir, **kwargs)


__all__ = ["ANSWER", "WORKER_LOG", "BackgroundEval", "check_eval_args", "make_periodic_eval"]
