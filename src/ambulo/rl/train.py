"""train: PPO (rsl-rl-lib) on a registered task, with TensorBoard, checkpoints and resume."""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import io
import os
import statistics
from pathlib import Path
from typing import Any

import torch
from rsl_rl.runners import OnPolicyRunner
from tqdm import tqdm

import ambulo
from ambulo import envs

from . import runs
from .config import ppo_cfg
from .vecenv import RslRlVecEnv

_METRICS = ("iteration", "env_steps", "mean_reward", "mean_episode_length_s", "steps_per_s",
            "collect_s", "learn_s", "action_std")


class AmbuloRunner(OnPolicyRunner):
    """``OnPolicyRunner`` whose checkpoints are atomic and carry the RNG states for resume."""

    env: RslRlVecEnv

    def save(self, path: str, infos: dict | None = None) -> None:
        saved = self.alg.save()
        saved["iter"] = self.current_learning_iteration
        saved["infos"] = {
            **(infos or {}),
            "env_rng": self.env.env.generator.get_state(),
            "torch_rng": torch.get_rng_state(),
        }
        runs.atomic_torch_save(saved, Path(path))
        self.logger.save_model(path, self.current_learning_iteration)

    def load_for_resume(self, path: Path) -> int:
        """Load weights, optimizer and RNG states; return the next iteration to run."""
        infos = self.load(str(path), map_location=str(self.device)) or {}
        if "env_rng" in infos:
            self.env.env.generator.set_state(infos["env_rng"])
        if "torch_rng" in infos:
            torch.set_rng_state(infos["torch_rng"])
        self.current_learning_iteration += 1  # the checkpoint's iteration is complete
        return self.current_learning_iteration


def _install_progress(runner: AmbuloRunner, run_dir: Path, start: int, total: int,
                      verbose: bool, step_dt_s: float) -> tqdm:
    """Replace rsl-rl's per-iteration console report by a progress bar (unless ``verbose``)
    and append each iteration's headline numbers to ``metrics.csv``."""
    bar = tqdm(total=total, initial=start, desc=f"train {run_dir.parent.name}", unit="it",
               disable=verbose)
    report = runner.logger.log
    metrics_file = run_dir / "metrics.csv"
    new_file = not metrics_file.exists()
    steps_per_it = runner.cfg["num_steps_per_env"] * runner.env.num_envs

    def log(**kwargs: Any) -> None:
        if verbose:
            report(**kwargs)
        else:
            with contextlib.redirect_stdout(io.StringIO()):
                report(**kwargs)
        logger, it = runner.logger, kwargs["it"]
        reward = statistics.mean(logger.rewbuffer) if logger.rewbuffer else float("nan")
        length = statistics.mean(logger.lenbuffer) * step_dt_s if logger.lenbuffer else float("nan")
        seconds = kwargs["collect_time"] + kwargs["learn_time"]
        row = [it, (it + 1) * steps_per_it, f"{reward:.4f}", f"{length:.3f}",
               int(steps_per_it / max(seconds, 1e-9)), f"{kwargs['collect_time']:.3f}",
               f"{kwargs['learn_time']:.3f}", f"{float(kwargs['action_std'].detach().mean()):.4f}"]
        with open(metrics_file, "a", newline="") as f:
            csv.writer(f).writerow(row)
        bar.update(1)
        bar.set_postfix(reward=f"{reward:.2f}", ep_len_s=f"{length:.2f}", fps=row[4])

    if new_file:
        with open(metrics_file, "w", newline="") as f:
            csv.writer(f).writerow(_METRICS)
    runner.logger.log = log
    return bar


def train(task: str | None = None, *, num_envs: int | None = None,
          max_iterations: int | None = None, seed: int = 0, device: str = "cpu",
          resume: str | os.PathLike | bool | None = None, log_root: str | os.PathLike = "runs",
          env_overrides: dict[str, Any] | None = None, ppo_overrides: dict[str, Any] | None = None,
          verbose: bool = False) -> Path:
    """Train ``task`` with PPO; return the run directory.

    Args:
      task: registered task name (optional when resuming a run folder).
      num_envs, max_iterations: override the task's PPO defaults (``ambulo.rl.config``).
        ``max_iterations`` counts from iteration 0, so a resumed run stops at the same total.
      seed: seeds the env and torch.
      resume: True for the task's latest run under ``log_root``, or a run folder/checkpoint:
        continue that run from its last complete checkpoint, in the same folder.
      env_overrides: task config fields to change, dotted keys reach nested ones
        (e.g. ``{"episode_length_s": 10.0, "physics.solver_iterations": 20}``); saved in run.json.
      verbose: print rsl-rl's full report each iteration instead of a progress bar.
    """
    if resume:
        run_dir = runs.resolve_run(task if resume is True else resume, log_root)
        info = runs.read_run_info(run_dir)
        if max_iterations is not None:
            info["ppo"]["max_iterations"] = max_iterations
        ppo = runs.ppo_from_info(info)
    else:
        if task is None:
            raise ValueError("name the task to train, e.g. `ambulo train cartpole`")
        # unknown names and bad overrides fail here, before any folder is made
        envs.make_cfg(task, **(env_overrides or {}))
        ppo = ppo_cfg(task, num_envs=num_envs, max_iterations=max_iterations,
                      **(ppo_overrides or {}))
        run_dir = runs.new_run_dir(task, log_root)
        info = {"task": task, "seed": seed, "device": device,
                "env_overrides": dict(env_overrides or {}), "ppo": dataclasses.asdict(ppo),
                "ambulo_version": ambulo.__version__}
        runs.write_run_info(run_dir, info)

    torch.manual_seed(info["seed"])
    env = runs.make_env_for_run(info, num_envs=ppo.num_envs)
    with contextlib.redirect_stdout(io.StringIO()) if not verbose else contextlib.nullcontext():
        runner = AmbuloRunner(RslRlVecEnv(env), ppo.to_rsl_rl(env.num_privileged_obs > 0),
                              log_dir=str(run_dir), device=str(env.device))
    runner.add_git_repo_to_log(ambulo.__file__)
    start = 0
    if resume:
        checkpoint = runs.latest_checkpoint(run_dir)
        start = runner.load_for_resume(checkpoint)
        print(f"resuming {run_dir} from {checkpoint.name} at iteration {start}")
    else:
        print(f"training {info['task']} with {ppo.num_envs} envs -> {run_dir}")
    remaining = ppo.max_iterations - start
    if remaining <= 0:
        print(f"{run_dir} already ran {start} of {ppo.max_iterations} iterations")
        return run_dir
    bar = _install_progress(runner, run_dir, start, ppo.max_iterations, verbose, env.step_dt_s)
    try:
        with contextlib.redirect_stdout(io.StringIO()) if not verbose else contextlib.nullcontext():
            runner.learn(remaining, init_at_random_ep_len=ppo.init_at_random_ep_len and not resume)
    finally:
        bar.close()
        env.close()
    print(f"checkpoints and TensorBoard logs in {run_dir} (tensorboard --logdir {run_dir})")
    return run_dir
