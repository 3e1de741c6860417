"""train_offpolicy: ``ambulo train TASK --algo fast-sac | fast-td3``, a run like PPO's.

The run folder, ``run.json`` (with ``"algo"`` and the ``"offpolicy"`` settings instead of
``"ppo"``), checkpoints, ``metrics.csv``, TensorBoard, ``--eval-every`` / ``--stop-at-criterion``
(``periodic_eval``), SIGINT/SIGTERM saves (``interrupt``) and resume are PPO's machinery; the
learner is ``offpolicy.OffPolicyRunner``. ``rl.train.train`` dispatches here by the algorithm
(given, or a resumed run's ``run.json``).
"""

from __future__ import annotations

import dataclasses
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch
from torch.utils.tensorboard import SummaryWriter

import ambulo
from ambulo import envs
from ambulo.engine import engine_class
from ambulo.utils.atomic import remove_partial_files

from . import distributed, interrupt, runs
from .episodes import EpisodeStats
from .eval_async import check_eval_args, make_periodic_eval
from .offpolicy import OffPolicyRunner, offpolicy_cfg
from .offpolicy.config import cfg_from_info
from .periodic_eval import PeriodicEval, resume_evals
from .progress import CriterionReached, TrainingProgress, end_training


def train_offpolicy(task: str | None, *, algo: str, num_envs: int | None = None,
                    max_iterations: int | None = None, seed: int | None = None, device: str | None = None,
                    resume_point: tuple[Path, Path] | None = None, log_root: str | os.PathLike = "runs",
                    env_overrides: dict[str, Any] | None = None, algo_overrides: dict[str, Any] | None = None,
                    verbose: bool = False, eval_every: int | None = None, stop_at_criterion: bool = False,
                    started_s: float | None = None,
                    report: Callable[[PeriodicEval], None] | None = None,
                    watch: Callable[[envs.RLEnv], Any] | None = None, init_from: Path | None = None,
                    eval_async: bool = False) -> Path:
    """Train ``task`` with ``algo``; return the run folder. Arguments as ``rl.train.train``'s;
    ``resume_point``: (run folder, checkpoint) of a run to continue (``train._resume_point``),
    ``report``: prints the time to the criterion at the end; ``watch``: as ``train``'s (the web
    viewer on the training env, its curves fed each iteration); ``init_from``: the checkpoint
    (from ``runs.resolve_init_from``) whose networks a new run starts from
    (``OffPolicyRunner.load_for_init``)."""
    started_s = time.monotonic() if started_s is None else started_s
    check_eval_args(eval_every, stop_at_criterion, eval_async)
    if distributed.current().distributed:
        raise ValueError(f"--algo {algo} trains in one process; start it without torchrun")
    if resume_point is not None:
        run_dir, checkpoint = resume_point
        info = runs.read_run_info(run_dir)
        runs.note_kept_settings(info, num_envs=num_envs, seed=seed, device=device)
        if remove_partial_files(run_dir):
            print(f"removed the partial files a killed run left in {run_dir}", file=sys.stderr)
        if max_iterations is not None:
            info["offpolicy"]["max_iterations"] = max_iterations
        cfg = cfg_from_info(info)
    else:
        if task is None:
            raise ValueError("name the task to train, e.g. `ambulo train cartpole --algo fast-sac`")
        envs.make_cfg(task, **(env_overrides or {}))
        engine_class(device or "cpu")
        cfg = offpolicy_cfg(task, algo, num_envs=num_envs, max_iterations=max_iterations, **(algo_overrides or {}))
        info = {"task": task, "algo": algo, "seed": 0 if seed is None else seed, "device": device or "cpu",
                "env_overrides": dict(env_overrides or {}), "offpolicy": dataclasses.asdict(cfg),
                "ambulo_version": ambulo.__version__, "world_size": 1}
        if init_from is not None:
            info["init_from"] = str(init_from)
        run_dir = runs.new_run_dir(task, log_root)
        runs.write_run_info(run_dir, info)

    torch.manual_seed(info["seed"])
    env = runs.make_env_for_run(info, num_envs=cfg.num_envs, seed=info["seed"], device=info["device"])
    episodes = EpisodeStats(cfg.num_envs, env.device)
    writer = SummaryWriter(log_dir=str(run_dir), flush_secs=10)
    progress_box: list[TrainingProgress] = []
    with runs.refused_before_training(run_dir, env.close, writer.close, discard=resume_point is None):
        runner = OffPolicyRunner(env, cfg, episodes=episodes, writer=writer, seed=info["seed"], run_dir=run_dir,
                                 on_iteration=lambda *args: progress_box[0].iteration_done(*args))
        if init_from is not None:
            runner.load_for_init(init_from, info["task"])
    runner.started_s = started_s
    start = 0
    if resume_point is not None:
        start = runner.load_for_resume(checkpoint)
        started_s = runner.started_s  # the earlier segments' wall time included
        print(f"resuming {run_dir} from {checkpoint.name} at iteration {start} (the replay ring refills)")
    else:
        weights = f" from the weights of {init_from}" if init_from is not None else ""
        print(f"training {info['task']} with {cfg.algo}, {cfg.num_envs} envs{weights} -> {run_dir}")
    remaining = cfg.max_iterations - start
    if remaining <= 0:
        print(f"{run_dir} already ran {start} of {cfg.max_iterations} iterations")
        env.close()
        writer.close()
        return run_dir
    steps_per_iteration = cfg.num_steps_per_env * cfg.num_envs
    periodic = None
    if eval_every:
        periodic = make_periodic_eval(info, run_dir, every=eval_every, started_s=started_s,
                                      steps_per_iteration=steps_per_iteration, device=str(env.device), start=start,
                                      eval_async=eval_async)
    elif resume_point is not None:
        resume_evals(run_dir, start)
    stop = interrupt.StopRequest()
    watcher = watch(env) if watch is not None else None
    curves = {} if watcher is None else {"on_scalars": watcher.add_scalars}
    progress = TrainingProgress(runner, run_dir, episodes=episodes, start=start, total=cfg.max_iterations,
                                verbose=verbose, step_dt_s=env.step_dt_s, steps_per_iteration=steps_per_iteration,
                                stop=stop, periodic=periodic, stop_at_criterion=stop_at_criterion,
                                eval_every=eval_every, **curves)
    progress_box.append(progress)
    try:
        interrupt.learn(runner, stop, run_dir, remaining, init_at_random_ep_len=resume_point is None)
        if periodic is not None:  # evaluations still running in a background worker
            periodic.finish()
    except CriterionReached:
        pass
    finally:
        end_training(progress, watcher, env, writer, periodic)
    if periodic is not None and report is not None:
        report(periodic)
    print(f"checkpoints and TensorBoard logs in {run_dir} (tensorboard --logdir {run_dir})")
    return run_dir


__all__ = ["train_offpolicy"]
