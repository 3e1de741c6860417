"""ProgressWriter: rsl-rl-lib's ``LogWriter`` extension point, writing TensorBoard and closing iterations.

rsl-rl-lib's ``Logger`` builds its writer from ``train_cfg["logger"]`` (``{"class_name": ...}``)
and hands it every scalar of an iteration from ``Logger.log``, which the runner calls after the
update and before its periodic save. This writer passes them to TensorBoard (the events rsl-rl's
default writer would write) and, once an iteration's three per-iteration scalars
(``ITERATION_TAGS``) are in, calls ``on_iteration(it, collect_s, learn_s, action_std)``: ambulo's
metrics row, progress bar, periodic evaluation and early stop (``progress.TrainingProgress``).

``Train/mean_reward`` and ``Train/mean_episode_length`` come from ambulo's ``EpisodeStats``
instead of rsl-rl's buffers, so a resumed run continues them from its checkpoint.
"""

from __future__ import annotations

from collections.abc import Callable

from rsl_rl.utils.log_writer import LogWriter
from torch.utils.tensorboard import SummaryWriter

ITERATION_TAGS = ("Perf/collection_time", "Perf/learning_time", "Policy/mean_std")
"""Scalars rsl-rl logs once every iteration, at the iteration's number: collect s, learn s,
the policy's mean action std."""
EPISODE_TAGS = ("Train/mean_reward", "Train/mean_episode_length")
"""rsl-rl's episode means, replaced by ambulo's (``means``)."""


class ProgressWriter(LogWriter):
    """TensorBoard events in ``log_dir`` plus ``on_iteration`` at the end of each logged iteration.

    Args:
      log_dir: the run folder (rsl-rl passes it).
      on_iteration: ``(iteration, collect_s, learn_s, action_std)`` once those are logged.
      means: ``() -> (mean return, mean episode length in env steps)``, None before an episode ended.
    """

    def __init__(self, log_dir: str, on_iteration: Callable[[int, float, float, float], None],
                 means: Callable[[], tuple[float | None, float | None]]):
        self.tensorboard = SummaryWriter(log_dir=log_dir, flush_secs=10)
        self.on_iteration, self.means = on_iteration, means
        self._pending: dict[str, float] = {}
        self._iteration: int | None = None

    @classmethod
    def factory(cls, on_iteration: Callable[[int, float, float, float], None],
                means: Callable[[], tuple[float | None, float | None]]) -> Callable[..., ProgressWriter]:
        """A ``class_name`` for ``train_cfg["logger"]``: rsl-rl deep-copies that config and calls
        ``class_name(log_dir=...)``; a function is copied as itself, these callbacks with it."""
        def make(log_dir: str) -> ProgressWriter:
            return cls(log_dir, on_iteration, means)
        return make

    def add_scalar(self, tag: str, scalar_value: float, global_step: int) -> None:
        if tag.startswith(EPISODE_TAGS):
            return  # ambulo's own, at the end of the iteration
        self.tensorboard.add_scalar(tag, scalar_value, global_step)
        if tag not in ITERATION_TAGS:
            return
        if global_step != self._iteration:
            self._iteration, self._pending = global_step, {}
        self._pending[tag] = float(scalar_value)
        if len(self._pending) == len(ITERATION_TAGS):
            self._close_iteration(global_step)

    def _close_iteration(self, iteration: int) -> None:
        reward, length = self.means()
        if reward is not None:
            self.tensorboard.add_scalar(EPISODE_TAGS[0], reward, iteration)
            self.tensorboard.add_scalar(EPISODE_TAGS[1], length, iteration)
        collect_s, learn_s, action_std = (self._pending[t] for t in ITERATION_TAGS)
        self._pending = {}
        self.on_iteration(iteration, collect_s, learn_s, action_std)

    def flush(self) -> None:
        self.tensorboard.flush()

    def stop(self) -> None:
        self.tensorboard.close()


__all__ = ["ITERATION_TAGS", "ProgressWriter"]
