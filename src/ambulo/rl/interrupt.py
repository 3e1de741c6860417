"""Stopping training on SIGINT (Ctrl-C) or SIGTERM (a scheduler's kill) without losing work.

The first signal only sets a flag: the iteration under way finishes (its metrics row is
written), its checkpoint ``model_<it>.pt`` is saved, and ``TrainingInterrupted`` says how to
resume. Stopping in the middle of an iteration would checkpoint a half-updated policy, and
rsl-rl's loop has no stop hook, so the flag is checked at the end of each iteration
(``StopRequest.check``, from ``progress.TrainingProgress``): on rank 0 when rsl-rl's logger has
handed the iteration to ambulo's log writer, after the update and before rsl-rl's own save.
A second signal stops at once (``TrainingInterrupted`` with ``saved=False``); a save it cuts
short leaves no file behind, because checkpoints are written atomically.
A ``kill -9`` cannot be caught: it loses the iterations after the last periodic checkpoint.
"""

from __future__ import annotations

import signal
import sys
import threading
from pathlib import Path

from .checkpoints import checkpoints

_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class TrainingInterrupted(KeyboardInterrupt):
    """Training stopped by a signal. ``checkpoint`` is the newest checkpoint on disk (the one
    saved on the way out when ``saved``), ``exit_status`` the shell's 128 + signal number."""

    def __init__(self, signum: int, run_dir: Path, checkpoint: Path | None, saved: bool):
        self.signum, self.run_dir, self.checkpoint, self.saved = signum, run_dir, checkpoint, saved
        self.exit_status = 128 + signum
        name = signal.Signals(signum).name
        if saved:
            what = f"stopped by {name}: saved {checkpoint.name} in {run_dir}"
        elif checkpoint is not None:
            what = (f"stopped at once by a second {name}: the iteration under way was not saved; "
                    f"the newest checkpoint is {checkpoint.name} in {run_dir}")
        else:
            what = f"stopped by {name} before the first checkpoint of {run_dir}"
        fix = (f"continue with `ambulo train --resume {run_dir}`" if checkpoint is not None
               else "start a new run with `ambulo train <task>`")
        super().__init__(f"{what}; {fix}")


class _StopAfterIteration(BaseException):
    """Raised by ``StopRequest.check`` at the end of an iteration (BaseException: nothing in
    rsl-rl that catches ``Exception`` may swallow it)."""


class _StopNow(BaseException):
    """Raised by the signal handler on the second signal."""


class StopRequest:
    """While entered (in the main thread; elsewhere signals cannot be caught), SIGINT and
    SIGTERM set ``signum`` instead of ending the process; a second one raises at once."""

    def __init__(self):
        self.signum: int | None = None
        self._previous: dict[int, object] = {}

    def __enter__(self) -> StopRequest:
        if threading.current_thread() is threading.main_thread():
            for sig in _SIGNALS:
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for sig, handler in self._previous.items():  # None: a handler not set from Python
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)
        self._previous.clear()

    def _handle(self, signum: int, frame) -> None:
        if self.signum is not None:
            raise _StopNow(signum)
        self.signum = signum
        print(f"\n{signal.Signals(signum).name}: finishing this iteration to save a checkpoint "
              "(send it again to stop at once)", file=sys.stderr, flush=True)

    def check(self) -> None:
        """End training here if a signal came (call once an iteration is complete)."""
        if self.signum is not None:
            raise _StopAfterIteration


def learn(runner, stop: StopRequest, run_dir: Path, num_iterations: int, **kwargs) -> None:
    """``runner.learn(num_iterations, **kwargs)``; on a signal, save the complete iteration and
    raise ``TrainingInterrupted``."""
    try:
        with stop:
            try:
                runner.learn(num_iterations, **kwargs)
                return
            except _StopAfterIteration:
                path = Path(run_dir) / f"model_{runner.current_learning_iteration}.pt"
                runner.save(str(path))
    except _StopNow as now:
        found = checkpoints(run_dir)
        raise TrainingInterrupted(now.args[0], run_dir, found[-1][1] if found else None,
                                  saved=False) from None
    finally:
        writer = getattr(runner.logger, "writer", None)
        if writer is not None and hasattr(writer, "flush"):
            writer.flush()  # TensorBoard events up to the stop
    raise TrainingInterrupted(stop.signum, run_dir, path, saved=True)
