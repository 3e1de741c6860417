"""train: PPO (rsl-rl-lib) on a registered task, with TensorBoard, checkpoints and resume."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch
from rsl_rl.runners import OnPolicyRunner

import ambulo
from ambulo import envs
from ambulo.engine import engine_class
from ambulo.utils.atomic import remove_partial_files

from . import distributed, interrupt, runs
from .checkpoints import check_same_shapes
from .config import PpoCfg, ppo_cfg
from .episodes import EpisodeStats
from .eval_async import check_eval_args, make_periodic_eval
from .log_writer import ProgressWriter
from .logger import EpisodeLogger
from .periodic_eval import PeriodicEval, resume_evals
from .ppo import AmbuloPPO
from .progress import CriterionReached, TrainingProgress, end_training
from .sampling import SyncFreeGaussian
from .symmetry import env_mirror, mirror_augmentation
from .vecenv import RslRlVecEnv


class AmbuloRunner(OnPolicyRunner):
    """``OnPolicyRunner`` whose checkpoints are atomic and carry what resume needs: the RNG
    states, and the episode returns and lengths of the last 100 episodes (``episodes``), so the
    running means in ``metrics.csv`` and TensorBoard continue where they were instead of
    restarting empty. It overrides public methods only (``learn``, ``save``); ambulo's
    per-iteration work comes in through the logger's writer (``log_writer.ProgressWriter``)."""

    env: RslRlVecEnv
    episodes: EpisodeStats | None = None
    """The main rank's episode statistics (set by ``train``)."""

    def __init__(self, env: RslRlVecEnv, train_cfg: dict, log_dir: str | None = None, device: str = "cpu"):
        super().__init__(env, train_cfg, log_dir=log_dir, device=device)
        self.started_s = time.monotonic()
        """``time.monotonic()`` the run's wall time counts from (``train`` sets the CLI's start);
        checkpoints keep the time elapsed, and a resume moves this back by it, so evaluations and
        the time to a criterion count every segment of a run that was stopped and resumed."""
        # rsl-rl's logger reads finished episodes back to the host every step; ambulo's keeps
        # them on the device (``logger.EpisodeLogger``)
        self.logger = EpisodeLogger.adopt(self.logger, env.episodes)

    def learn(self, num_learning_iterations: int, init_at_random_ep_len: bool = False) -> None:
        if self.alg.is_multi_gpu and not self.is_distributed:  # CPU ranks (ppo.AmbuloPPO): rank 0's weights
            self.alg.broadcast_parameters()
        super().learn(num_learning_iterations, init_at_random_ep_len)

    def save(self, path: str, infos: dict | None = None) -> None:
        if not distributed.current().is_main:
            return  # rank 0 writes the run folder
        saved = self.alg.save()
        saved["iter"] = self.current_learning_iteration
        saved["infos"] = {
            **(infos or {}),
            "env_rng": self.env.env.generator.get_state(),
            "torch_rng": torch.get_rng_state(),
            "episode_returns": self.episodes.returns() if self.episodes is not None else [],
            "episode_lengths": self.episodes.lengths() if self.episodes is not None else [],
            "wall_s": time.monotonic() - self.started_s,
        }
        runs.atomic_torch_save(saved, Path(path))
        self.logger.save_model(path, self.current_learning_iteration)

    def load_for_resume(self, path: Path) -> int:
        """Load weights, optimizer and RNG states; return the next iteration to run."""
        infos = self.load(str(path), map_location=str(self.device)) or {}
        if "env_rng" in infos:
            self.env.env.generator.set_state(infos["env_rng"].cpu())
        if "torch_rng" in infos:
            torch.set_rng_state(infos["torch_rng"].cpu())
        if self.episodes is not None:
            self.episodes.restore(infos.get("episode_returns", []), infos.get("episode_lengths", []))
        self.started_s -= float(infos.get("wall_s", 0.0))  # older checkpoints lack it: this segment only
        self.current_learning_iteration += 1  # the checkpoint's iteration is complete
        return self.current_learning_iteration

    def load_for_init(self, path: Path, task: str) -> None:
        """``ambulo train --init-from``: the networks of ``path`` (actor, critic and their
        observation normalizers), after checking they have this run's shapes; not its iteration,
        RNG states or episode statistics (a new run starts at 0).

        Nor its optimizer: a fine-tune usually changes the reward, so the value targets move and
        Adam's moment estimates of the old run's gradients would steer the first updates wrongly;
        and the learning rate (adaptive or scheduled) restarts from this run's setting instead of
        the rate the old run ended at. Adam starts fresh, as rsl-rl's own ``load_cfg`` allows."""
        saved = torch.load(path, weights_only=False, map_location=str(self.device))
        nets = ("actor_state_dict", "critic_state_dict")
        here = self.alg.save()
        check_same_shapes(path, saved, {net: here[net] for net in nets}, task)
        self.alg.load(saved, {"actor": True, "critic": True}, strict=True)


def runner_cfg(env: envs.RLEnv, ppo: PpoCfg) -> dict[str, Any]:
    """rsl-rl-lib's ``train_cfg`` as ``ambulo train`` runs it: the task's PPO settings
    (``PpoCfg.to_rsl_rl``) with ambulo's algorithm class, the Gaussian head that samples without
    a host sync (``sampling.SyncFreeGaussian``) and the NaN check moved from every step into the
    algorithm, once an iteration (``ppo.AmbuloPPO``). Benchmarks build from it to time what
    training runs; the log writer is added by ``train``."""
    cfg = ppo.to_rsl_rl(env.num_privileged_obs > 0)
    cfg["algorithm"]["class_name"] = AmbuloPPO
    if ppo.symmetry:
        env_mirror(env)  # refuse an asymmetric robot or a term without a mirror rule before training
        cfg["algorithm"]["symmetry_cfg"] = {"use_data_augmentation": True, "use_mirror_loss": False,
                                            "mirror_loss_coeff": 0.0, "data_augmentation_func": mirror_augmentation}
    cfg["actor"]["distribution_cfg"]["class_name"] = SyncFreeGaussian
    cfg["check_for_nan"] = False
    return cfg


def _make_runner(env, ppo, run_dir: Path, rank: distributed.Rank, episodes: EpisodeStats | None,
                 progress_box: list) -> AmbuloRunner:
    """The runner, with ambulo's classes (``runner_cfg``) and log writer in its config (rsl-rl's
    extension points). ``progress_box`` receives the ``TrainingProgress`` once it exists (it needs
    the runner)."""
    cfg = runner_cfg(env, ppo)
    cfg["logger"] = {"class_name": ProgressWriter.factory(
        on_iteration=lambda *args: progress_box[0].iteration_done(*args),
        means=lambda: episodes.means())}
    cpu_ranks = rank.distributed and str(env.device) == "cpu"
    if cpu_ranks:
        distributed.init_cpu_group(rank)
    with distributed.single_process_view() if cpu_ranks else contextlib.nullcontext():
        runner = AmbuloRunner(RslRlVecEnv(env, episodes), cfg, log_dir=str(run_dir) if rank.is_main else None,
                              device=str(env.device))
    runner.episodes = episodes
    return runner


def _resume_point(task: str | None, resume: str | os.PathLike | bool,
                  log_root: str | os.PathLike) -> tuple[Path, Path]:
    """The run folder to resume and its newest readable checkpoint, found before anything is
    built; ``RunError`` in one line when the run has none."""
    run_dir = runs.resolve_run(task if resume is True else resume, log_root)
    try:
        return run_dir, runs.latest_valid_checkpoint(run_dir)
    except runs.CheckpointError as err:
        info = runs.read_run_info(run_dir)
        raise runs.CheckpointError(f"cannot resume: {err.problem}",
                                   f"start a new run with `ambulo train {info.get('task', '<task>')}`"
                                   ) from None


def _saved_at(reached: dict[str, Any]) -> str:
    """When the judged checkpoint was saved, for an evaluation in the background (``eval_async``)."""
    if not reached.get("eval_async"):
        return ""
    return f" saved at {reached['checkpoint_wall_s'] / 60:.2f} min, judged in the background"


def _report_time_to_criterion(periodic: PeriodicEval) -> None:
    reached = periodic.reached
    names = " and ".join(c.name for c in periodic.task.criteria)
    if reached is None:
        print(f"{names} not reached (evaluations in {periodic.run_dir / 'evals.csv'})")
        return
    confirmed = " (confirmed on the CPU engine)" if periodic.confirm else ""
    print(f"{names} reached{confirmed} at iteration {reached['iteration']} after {reached['wall_s'] / 60:.2f} min "
          f"({reached['env_steps']:,} env steps, {reached['checkpoint']}{_saved_at(reached)}; "
          f"{periodic.run_dir / 'time_to_criterion.json'})")


def train(task: str | None = None, *, num_envs: int | None = None,
          max_iterations: int | None = None, seed: int | None = None, device: str | None = None,
          resume: str | os.PathLike | bool | None = None, log_root: str | os.PathLike = "runs",
          env_overrides: dict[str, Any] | None = None, ppo_overrides: dict[str, Any] | None = None,
          verbose: bool = False, eval_every: int | None = None, stop_at_criterion: bool = False,
          started_s: float | None = None, watch: Callable[[envs.RLEnv], Any] | None = None,
          algo: str | None = None, algo_overrides: dict[str, Any] | None = None,
          init_from: str | os.PathLike | None = None, eval_async: bool = False) -> Path:
    """Train ``task`` with PPO (or ``algo``); return the run directory.

    Args:
      task: registered task name (optional when resuming a run folder).
      num_envs, max_iterations: override the task's PPO defaults (``ambulo.rl.config``).
        ``max_iterations`` counts from iteration 0, so a resumed run stops at the same total.
      seed: seeds the env and torch (default 0).
      device: cpu or cuda[:N] (default cpu).
      resume: True for the task's latest run under ``log_root`` (skipping runs that stopped
        before their first checkpoint), or a run folder/checkpoint: continue that run from its
        newest readable checkpoint, in the same folder. The run keeps its run.json settings:
        ``num_envs``, ``seed`` and ``device`` that differ are reported and not applied.
      env_overrides: task config fields to change, dotted keys reach nested ones
        (e.g. ``{"episode_length_s": 10.0, "physics.solver_iterations": 20}``); saved in run.json.
      verbose: print rsl-rl's full report each iteration instead of a progress bar.
      init_from: a checkpoint file, or a run folder (its newest readable checkpoint): a new run
        whose networks start from that checkpoint's weights (``AmbuloRunner.load_for_init``: a
        fresh optimizer, iteration 0), with its own settings; its run.json records the checkpoint
        under ``init_from``. The networks must match the task's as configured, and ``algo`` must
        be the algorithm that trained it (``RunError`` in one line otherwise, no folder left).
      eval_every: evaluate the policy every this many iterations as ``ambulo eval`` does and
        time the first evaluation that meets the task's criteria (``ambulo.rl.periodic_eval``).
      stop_at_criterion: with ``eval_every``, end training at that first success. A success on
        an engine other than the CPU engine (a GPU's) counts only once the same policy meets the
        criteria on the CPU engine too (``ambulo.rl.periodic_eval``).
      eval_async: with ``eval_every``, evaluate in a worker process while training goes on
        (``ambulo.rl.eval_async``); one process only.
      started_s: ``time.monotonic()`` the timing counts from (default: now; the CLI passes
        the time it started).
      algo: ``"ppo"`` (default) or an off-policy learner, ``"fast-sac"`` or ``"fast-td3"``
        (``ambulo.rl.train_offpolicy``, whose settings ``algo_overrides`` changes as
        ``ppo_overrides`` does PPO's); a resumed run keeps the algorithm of its run.json.
      watch: called with the training env before the first iteration (main rank only): ``ambulo
        train --viewer web`` opens the web viewer on it (``ambulo.viewer.serve``: an app this
        package may not import). What it returns gets ``add_scalars(iteration, {name: value})``
        after every iteration (``progress.TrainingProgress``: the curves beside the scene) and
        ``close()`` when training ends, however it ends.

    SIGINT and SIGTERM during training save the iteration under way and raise
    ``interrupt.TrainingInterrupted`` (see ``ambulo.rl.interrupt``).
    """
    started_s = time.monotonic() if started_s is None else started_s
    check_eval_args(eval_every, stop_at_criterion, eval_async)
    if init_from is not None and resume:
        raise ValueError("init_from starts a new run; resume continues one: give one of them")
    resume_point = _resume_point(task, resume, log_root) if resume else None
    init_point = runs.resolve_init_from(init_from) if init_from is not None else None
    run_algo = runs.read_run_info(resume_point[0]).get("algo", "ppo") if resume_point else algo or "ppo"
    if algo is not None and algo != run_algo:
        raise ValueError(f"{resume_point[0]} was trained with {run_algo}, not {algo}; drop the algorithm "
                         "to resume it, or start a new run")
    if init_point is not None and init_point[1] != run_algo:
        raise runs.RunError(f"cannot init a {run_algo} run from {init_point[0]}: {init_point[1]} trained it",
                            f"add --algo {init_point[1]}, or init from a {run_algo} run")
    init_checkpoint = init_point[0] if init_point is not None else None
    if run_algo != "ppo":
        from .train_offpolicy import train_offpolicy

        return train_offpolicy(task, algo=run_algo, num_envs=num_envs, max_iterations=max_iterations, seed=seed,
                               device=device, resume_point=resume_point, log_root=log_root,
                               env_overrides=env_overrides, algo_overrides=algo_overrides, verbose=verbose,
                               eval_every=eval_every, stop_at_criterion=stop_at_criterion, started_s=started_s,
                               report=_report_time_to_criterion, watch=watch, init_from=init_checkpoint,
                               eval_async=eval_async)
    rank = distributed.current()
    if eval_async and rank.distributed:
        raise ValueError("--eval-async evaluates in one worker beside one training process; a data-parallel "
                         "run evaluates across its ranks: drop --eval-async")
    if resume:
        run_dir, checkpoint = resume_point
        info = runs.read_run_info(run_dir)
        if rank.is_main:
            runs.note_kept_settings(info, num_envs=num_envs, seed=seed, device=device)
        if rank.is_main and remove_partial_files(run_dir):
            print(f"removed the partial files a killed run left in {run_dir}", file=sys.stderr)
        if max_iterations is not None:
            info["ppo"]["max_iterations"] = max_iterations
        ppo = runs.ppo_from_info(info)
    else:
        if task is None:
            raise ValueError("name the task to train, e.g. `ambulo train cartpole`")
        # unknown names, bad overrides and a device without an engine fail here, before any folder is made
        envs.make_cfg(task, **(env_overrides or {}))
        engine_class(device or "cpu")
        ppo = ppo_cfg(task, num_envs=num_envs, max_iterations=max_iterations,
                      **(ppo_overrides or {}))
        info = {"task": task, "seed": 0 if seed is None else seed, "device": device or "cpu",
                "env_overrides": dict(env_overrides or {}), "ppo": dataclasses.asdict(ppo),
                "ambulo_version": ambulo.__version__, "world_size": rank.world_size}
        if init_checkpoint is not None:
            info["init_from"] = str(init_checkpoint)
        # rank 0 owns the run folder; the other ranks write nothing
        run_dir = runs.new_run_dir(task, log_root) if rank.is_main else Path(log_root) / task / f"rank{rank.rank}"
        if rank.is_main:
            runs.write_run_info(run_dir, info)

    torch.manual_seed(info["seed"] + rank.rank)  # each rank collects its own experience
    env = runs.make_env_for_run(info, num_envs=ppo.num_envs, seed=info["seed"] + rank.rank,
                                device=distributed.rank_device(info["device"], rank))
    episodes = EpisodeStats(ppo.num_envs, env.device) if rank.is_main else None
    progress_box: list[TrainingProgress] = []
    # (rsl-rl opens its TensorBoard writer in ``learn``: none to close yet)
    with runs.refused_before_training(run_dir, env.close, discard=rank.is_main and not resume):
        with contextlib.redirect_stdout(io.StringIO()) if not verbose else contextlib.nullcontext():
            runner = _make_runner(env, ppo, run_dir, rank, episodes, progress_box)
        if init_checkpoint is not None:
            runner.load_for_init(init_checkpoint, info["task"])
    runner.add_git_repo_to_log(ambulo.__file__)
    runner.started_s = started_s
    start = 0
    if resume:
        start = runner.load_for_resume(checkpoint)
        started_s = runner.started_s  # the earlier segments' wall time included
        print(f"resuming {run_dir} from {checkpoint.name} at iteration {start}")
    elif rank.is_main:
        ranks = f" x {rank.world_size} ranks" if rank.distributed else ""
        weights = f" from the weights of {init_checkpoint}" if init_checkpoint is not None else ""
        print(f"training {info['task']} with {ppo.num_envs} envs{ranks}{weights} -> {run_dir}")
    remaining = ppo.max_iterations - start
    if remaining <= 0:
        print(f"{run_dir} already ran {start} of {ppo.max_iterations} iterations")
        env.close()
        return run_dir
    stop = interrupt.StopRequest()
    periodic = None
    if eval_every:  # every rank evaluates its share of the episodes; rank 0 records them
        periodic = make_periodic_eval(info, run_dir, every=eval_every, started_s=started_s,
                                      steps_per_iteration=ppo.num_steps_per_env * ppo.num_envs * rank.world_size,
                                      device=str(env.device), start=start, rank=rank, eval_async=eval_async)
    elif resume and rank.is_main:  # evaluations of a crashed run's later iterations go, with or without --eval-every
        resume_evals(run_dir, start)
    watcher = watch(env) if watch is not None and rank.is_main else None
    progress = TrainingProgress(runner, run_dir, episodes=episodes, start=start, total=ppo.max_iterations,
                                verbose=verbose, step_dt_s=env.step_dt_s,
                                # env steps of all ranks: each collects its own num_envs x rollout
                                steps_per_iteration=ppo.num_steps_per_env * ppo.num_envs * rank.world_size,
                                stop=stop, periodic=periodic, stop_at_criterion=stop_at_criterion,
                                eval_every=eval_every, rank=rank,
                                on_scalars=None if watcher is None else watcher.add_scalars)
    progress_box.append(progress)
    if not rank.is_main:
        runner.alg.after_update = progress.follow
    try:
        with contextlib.redirect_stdout(io.StringIO()) if not verbose else contextlib.nullcontext():
            interrupt.learn(runner, stop, run_dir, remaining,
                            init_at_random_ep_len=ppo.init_at_random_ep_len and not resume)
            if periodic is not None:  # evaluations still running in a background worker
                periodic.finish()
    except CriterionReached:
        pass
    finally:
        end_training(progress, watcher, env, periodic)
    distributed.leave_group()  # every rank gets here together: stop, criterion or the last iteration
    if periodic is not None and rank.is_main:
        _report_time_to_criterion(periodic)
    if not rank.is_main:
        return run_dir
    print(f"checkpoints and TensorBoard logs in {run_dir} (tensorboard --logdir {run_dir})")
    return run_dir
