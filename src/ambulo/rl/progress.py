"""What ambulo does at the end of every training iteration, on each rank.

Rank 0 (``TrainingProgress.iteration_done``, called by ``log_writer.ProgressWriter`` once rsl-rl
has logged the iteration, or by ``offpolicy.OffPolicyRunner``): append the headline numbers to
``metrics.csv`` (from ``start``: rows of a killed run's later iterations are dropped; on a task
with a terrain curriculum also the robots' mean level, ``terrain_level_reader``), advance the
progress bar (unless ``verbose``, when rsl-rl's own report prints instead), evaluate when
``periodic`` is due, end training there if ``stop`` was asked or (``stop_at_criterion``) the
criteria hold, and hand the iteration's numbers to ``on_scalars`` (``training_scalars``,
``evaluation_scalars``: the web viewer's curves).

The other ranks (``TrainingProgress.follow``, called by ``ppo.AmbuloPPO`` after each update):
only the work every rank must share, at the same point of the iteration: the stop request, their
share of a due evaluation (``periodic``: each rank has one, ``periodic_eval``), and rank 0's
decision at an evaluation, so every rank stops at the same iteration.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch
from tqdm import tqdm

from . import distributed, interrupt
from .episodes import EpisodeStats
from .metrics import TERRAIN_LEVEL, MetricsCsv
from .periodic_eval import PeriodicEval, eval_due, summary


class CriterionReached(Exception):
    """Raised at the end of an iteration to end training once the task's criteria hold."""


class TrainingProgress:
    """The end-of-iteration work of one rank (see the module doc).

    Args:
      runner: the ``OnPolicyRunner`` (evaluations read its policy and save its checkpoint).
      episodes: the main rank's ``EpisodeStats`` (None on the other ranks).
      periodic: this rank's ``PeriodicEval`` (every rank of a data-parallel run has one: each
        evaluates its share of the episodes), an ``eval_async.BackgroundEval`` (``--eval-async``:
        a worker process evaluates while training goes on; its results are polled every
        iteration), or None without ``--eval-every``.
      start, total: the first iteration this process runs and the run's iteration count.
      step_dt_s: the env's policy step, s (episode lengths in the CSV are in seconds).
      steps_per_iteration: env steps of all ranks in one iteration.
      on_scalars: ``(iteration, {name: value})`` once an iteration is logged (``training_scalars``);
        it must not block (``ambulo.viewer``'s ``add_scalars`` queues them).
    """

    def __init__(self, runner, run_dir: Path, *, episodes: EpisodeStats | None, start: int, total: int,
                 verbose: bool, step_dt_s: float, steps_per_iteration: int, stop: interrupt.StopRequest,
                 periodic: PeriodicEval | None = None, stop_at_criterion: bool = False,
                 eval_every: int | None = None, rank: distributed.Rank | None = None,
                 on_scalars: Callable[[int, dict[str, float]], None] | None = None):
        self.runner, self.episodes, self.stop, self.periodic = runner, episodes, stop, periodic
        self.step_dt_s, self.steps_per_iteration = step_dt_s, steps_per_iteration
        rank = rank if rank is not None else distributed.Rank()  # one process: the main rank
        self.stop_at_criterion, self.eval_every, self.rank = stop_at_criterion, eval_every, rank
        self.on_scalars = on_scalars
        self.bar = tqdm(total=total, initial=start, desc=f"train {run_dir.parent.name}", unit="it",
                        disable=verbose or not rank.is_main)
        reader = terrain_level_reader(runner) if rank.is_main else None
        extra, self.terrain_level = reader if reader is not None else ((), None)
        self.metrics = MetricsCsv(run_dir / "metrics.csv", start, extra) if rank.is_main else None
        self._next_iteration = start
        """The iteration ``follow`` closes next (the other ranks have no logger to say it)."""

    @property
    def device(self) -> str:
        return str(self.runner.device)

    def means(self) -> tuple[float | None, float | None]:
        """(mean return, mean episode length s) of the last 100 episodes; None before any ended."""
        reward, length_steps = self.episodes.means()
        return reward, None if length_steps is None else length_steps * self.step_dt_s

    def iteration_done(self, iteration: int, collect_s: float, learn_s: float, action_std: float) -> None:
        """Rank 0, once rsl-rl logged ``iteration`` (and before its periodic checkpoint)."""
        reward, length_s = self.means()
        extras = {} if self.terrain_level is None else self.terrain_level()
        row = self.metrics.append(iteration, self.steps_per_iteration, reward, length_s, collect_s, learn_s,
                                  action_std, extras)
        self.bar.update(1)
        self.bar.set_postfix(reward=row[2] or "-", ep_len_s=row[3] or "-", fps=row[4])
        if self.on_scalars is not None:
            self.on_scalars(iteration, training_scalars(reward, length_s, float(row[4])))
        self.stop.check()
        if self.periodic is None:
            return
        due = self.periodic.due(iteration)
        finished = []
        if due:
            result = self.periodic(self.runner, iteration)  # None: handed to a background worker
            if result is not None:
                finished.append((iteration, result, time.monotonic() - self.periodic.started_s))
        finished += self.periodic.poll()  # the background worker's evaluations (``eval_async``)
        for evaluated, result, wall_s in finished:
            self.bar.write(summary(result, evaluated, wall_s))
            if self.on_scalars is not None:
                self.on_scalars(evaluated, evaluation_scalars(result))
        if due or finished:  # a data-parallel run evaluates in step: only `due` ever holds there
            reached = distributed.agree(self.periodic.reached is not None, self.rank, self.device)
            if self.stop_at_criterion and reached:
                raise CriterionReached

    def follow(self) -> None:
        """The other ranks, after each update: share rank 0's stop decision at an evaluation."""
        iteration = self._next_iteration
        self._next_iteration += 1
        self.stop.check()
        if eval_due(iteration, self.eval_every):
            if self.periodic is not None:  # this rank's share; the merge meets rank 0's in the same order
                self.periodic(self.runner, iteration)
            if distributed.agree(False, self.rank, self.device) and self.stop_at_criterion:
                raise CriterionReached

    def close(self) -> None:
        self.bar.close()


def terrain_level_reader(runner) -> tuple[tuple[str, ...], Callable[[], dict[str, float]]] | None:
    """(the ``metrics.csv`` columns, what reads their values: one host read, once an iteration) of
    ``runner``'s task env's terrain levels, or None when its levels do not move: the env's optional
    ``mean_terrain_level()`` (``envs.terrain_ground.TerrainGround``: None without a curriculum) as
    ``terrain_level``, then, where the env has ``terrain_levels_by_kind()``, each kind's mean as
    ``terrain_level_<kind>``. Both runners hold the task env wrapped in ``vecenv.RslRlVecEnv`` as
    ``runner.env``; a runner without one (tests' stand-ins) has no level."""
    env = getattr(getattr(runner, "env", None), "env", None)
    hook = getattr(env, "mean_terrain_level", None)
    if hook is None or hook() is None:  # fixed for the env's life: decided once, with the header
        return None
    by_kind = getattr(env, "terrain_levels_by_kind", None)
    kinds = by_kind() if by_kind is not None else None
    if kinds is None:
        return (TERRAIN_LEVEL,), lambda: {TERRAIN_LEVEL: float(hook())}
    columns = (TERRAIN_LEVEL, *(f"{TERRAIN_LEVEL}_{name}" for name in kinds[0]))

    def read() -> dict[str, float]:
        values = torch.cat([hook().reshape(1), by_kind()[1]]).tolist()  # one host read for all
        return dict(zip(columns, values))

    return columns, read


def end_training(progress: TrainingProgress, *others) -> None:
    """Close ``progress``, then each of ``others`` (the viewer, the env, writers, the periodic
    evaluation; None is skipped), in order: what every trainer does after learning, however it ended."""
    for thing in (progress, *others):
        if thing is not None:
            thing.close()


def training_scalars(mean_reward: float | None, mean_episode_length_s: float | None,
                     steps_per_s: float) -> dict[str, float]:
    """An iteration's curves: the mean return and episode length (s) of the last 100 episodes
    (absent before one ended) and env steps/s (the metrics.csv row's)."""
    scalars = {"env steps/s": steps_per_s}
    if mean_reward is not None:
        scalars["mean reward"] = mean_reward
    if mean_episode_length_s is not None:
        scalars["episode length (s)"] = mean_episode_length_s
    return scalars


def evaluation_scalars(result: dict[str, Any]) -> dict[str, float]:
    """An evaluation's curves (``--eval-every``): its fall rate, its step metrics (humanoid-walk:
    the velocity errors) and each of the task's criteria, 1 met or 0 not."""
    scalars = {"eval fall rate": result["fall_rate"]}
    scalars.update({f"eval {name[len('mean_'):]}": value for name, value in result.items()
                    if name.startswith("mean_abs")})
    scalars.update({f"criterion {name}": float(bool(result[name])) for name in result["criteria"]})
    return scalars


__all__ = ["CriterionReached", "TrainingProgress", "end_training", "evaluation_scalars", "terrain_level_reader",
           "training_scalars"]
