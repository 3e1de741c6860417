"""Evaluate the policy under training every K iterations and time the first success.

``ambulo train --eval-every K`` measures, at every K-th iteration, the policy being trained
exactly as ``ambulo eval`` measures a checkpoint (``run_episodes``: 100 full episodes of the
task's play variant, deterministic actions, the same seed each time so evaluations compare),
on a second env on the training device. Each evaluation saves the checkpoint it judged, adds
a row to ``<run>/evals.csv`` and ``eval/*`` scalars to TensorBoard, and the first one that
meets every criterion of the task writes ``<run>/time_to_criterion.json``: the wall-clock
time from the start of ``train`` (env build and kernel compile included) to that moment, so
"time to walk" is a measurement, not an estimate. A task evaluated in blocks (``eval_blocks``:
humanoid-walk-robust, nominal and 16 transfer corners, 20 episodes each) is measured so here
too: its criterion holds when it holds in every block, on each engine.

A criterion met only on the engine the policy trained on is not met: when the evaluation env
is not the CPU engine (MuJoCo C: a GPU run, or MuJoCo Warp on the CPU), an evaluation that meets
the criteria is repeated for the same policy on the CPU engine (100 episodes, same seed: the
numbers ``ambulo eval RUN --checkpoint model_<it>.pt --device cpu`` prints), and only when both
hold is the criterion reached (``time_to_criterion.json``, ``--stop-at-criterion``). Both
results go to ``evals.csv`` and ``time_to_criterion.json``, and the time counted includes the
CPU-engine evaluation. Why: policies at the bar passed on the GPU engine and missed on the CPU
engine (issue 22). The two evaluations differ in physics (float32 MuJoCo Warp, float64 MuJoCo;
``benchmarks/sim_to_sim.py`` measures it) and in the episodes they judge (a GPU env draws its
commands and resets from torch's CUDA generator, another sample than the CPU's); ``ambulo eval
--device cpu`` is the reference a user runs.

A resume from ``model_N.pt`` runs iterations N+1, N+2, ... again, so ``resume_evals`` first
drops the rows of iterations > N from ``evals.csv`` (rewritten atomically, as ``metrics.csv``),
and keeps ``time_to_criterion.json`` only if its iteration is <= N (see there).

In a data-parallel run (``rank``: W processes) every rank owns a ``PeriodicEval`` and evaluates
its share of the episodes on its own device (``eval_share``: ``num_episodes / W`` worlds, its own
seed stream); the shares' totals are merged so every rank holds the same result and takes the same
decision (the CPU-engine confirmation, split the same way, and the criteria). Rank 0 alone saves
the checkpoint and writes ``evals.csv``, ``time_to_criterion.json`` and TensorBoard. Every rank
must call it at the same iteration (``progress.TrainingProgress``). One process: rank 0 of 1, the
episodes ``ambulo eval`` runs; W ranks: those ``ambulo eval --num-gpus W`` runs (``eval_gpus``).
"""

from __future__ import annotations

import csv
import io
import json
import time
from pathlib import Path
from typing import Any

import torch

from ambulo import envs
from ambulo.engine import CpuEngine
from ambulo.utils.atomic import atomic_write_json, atomic_write_text

from . import runs
from .distributed import Rank
from .eval_blocks import eval_layout, worst_block, worst_block_text
from .eval_kinds import kinds_cell, most_falls_text, step_metrics
from .eval_share import eval_share, merge_over_ranks
from .evaluate import eval_episode_length_s, run_episodes
from .metrics import truncate_csv
from .vecenv import RslRlVecEnv

EVAL_COLUMNS = ("iteration", "wall_s", "env_steps", "fall_rate", "mean_episode_length_s",
                "mean_return", "metrics", "criteria_met", "cpu_engine_metrics", "cpu_engine_criteria_met",
                "worst_block", "cpu_engine_worst_block", "by_kind", "eval_engine")
"""``criteria_met``: on the evaluation env's engine (the training device's); ``cpu_engine_*``: the
same policy on the CPU engine, empty when not run (the evaluation env is the CPU engine, or its
evaluation did not meet the criteria). An evaluation in blocks (``eval_blocks``): ``fall_rate``
and ``metrics`` pool every block, ``criteria_met`` holds in every block, ``worst_block`` is the
block nearest to failing, its name then ``name=value`` pairs: its fall rate, its metrics and
``blocks_failed`` (``worst_block_from_text``); empty for a task without blocks. ``by_kind``: a
terrain task's fall rate and first step metric on each tile kind, ``kind:fall/err`` pairs
(``eval_kinds.kinds_cell``, read by ``kinds_from_text``), reported, not judged; empty without
terrain. ``eval_engine``: ``training`` when the row's first columns are the evaluation env's (the
training engine's), ``cpu`` when they are the CPU engine's: ``--eval-async``'s worker judges on the
CPU engine first (``evaluate(cpu_first=True)``) and runs the evaluation env only for a policy that
meets the criteria there (empty in files written before the column). Columns are only ever
appended: readers take them by name."""
TIME_FILE = "time_to_criterion.json"


def resume_evals(run_dir: Path, start: int) -> dict[str, Any] | None:
    """Make the evaluation records of ``run_dir`` those of a run resuming at iteration ``start``
    (its checkpoint's iteration + 1); return the kept ``time_to_criterion.json``, or None.

    ``evals.csv`` keeps the rows of iterations < ``start``: the later ones describe policies
    the crashed run trained after its checkpoint, which the resumed run trains again (and
    re-evaluates), so they would appear twice and out of order.

    ``time_to_criterion.json`` records the *first* evaluation that met the criteria. One from
    an iteration < ``start`` stays true after the resume: that evaluation is part of the resumed
    run's history (its checkpoint is kept, the iterations before it are not re-run), so it is
    kept and returned, and the resumed run must not overwrite it with a later success. One from
    an iteration >= ``start`` is removed: the policy it judged is discarded and retrained (its
    ``model_<it>.pt`` will be overwritten), so it would name a checkpoint and a time that no
    longer belong to the run; if the criteria hold again, the resumed run writes it anew. An
    unreadable one (not written by ambulo, whose writes are atomic) is removed as well.
    """
    run_dir = Path(run_dir)
    if (run_dir / "evals.csv").is_file():
        truncate_csv(run_dir / "evals.csv", EVAL_COLUMNS, start)
    path = run_dir / TIME_FILE
    if not path.is_file():
        return None
    try:
        reached = json.loads(path.read_text())
        iteration = reached["iteration"]
    except (OSError, ValueError, KeyError, TypeError):
        iteration = None
    if isinstance(iteration, int) and iteration < start:
        return reached
    path.unlink()
    return None


def is_cpu_engine(env: envs.RLEnv) -> bool:
    """Whether ``env`` runs on the CPU engine (MuJoCo C), whose evaluation is the reference."""
    return isinstance(env.engine, CpuEngine)


def eval_due(iteration: int, every: int | None) -> bool:
    """Whether iteration ``iteration`` (from 0) ends with an evaluation: every ``every``-th."""
    return bool(every) and (iteration + 1) % every == 0


class PeriodicEval:
    """Owns the evaluation env; ``__call__(runner, iteration)`` measures the runner's policy."""

    def __init__(self, info: dict[str, Any], run_dir: Path, *, every: int, started_s: float,
                 steps_per_iteration: int, num_episodes: int | None = None, seed: int = 12345,
                 device: str | None = None, start: int = 0, confirm_on_cpu_engine: bool = True,
                 rank: Rank | None = None, build_env: bool = True, records: bool = True):
        """``start`` > 0: the run resumes at that iteration (``resume_evals``).
        ``confirm_on_cpu_engine``: a success on another engine counts only once the CPU engine
        confirms it (see the module docstring). ``rank``: this process's place in a data-parallel
        run (default: the only one); ``device`` is then this rank's. ``num_episodes``: default 100,
        or the task's blocks' default (``eval_blocks``: the criteria are judged in every block).
        ``build_env`` False: no evaluation env here (``eval_async``: a worker process evaluates);
        ``records`` False: write nothing to the run folder (that worker: its parent records)."""
        self.task = envs.spec(info["task"])
        if not self.task.criteria:
            raise ValueError(f"--eval-every: task {info['task']!r} declares no success criterion to "
                             "time; drop --eval-every")
        self.layout = eval_layout(self.task, num_episodes)
        """The evaluation's episodes and blocks (the CPU-engine confirmation's too)."""
        self.info, self.num_episodes = info, self.layout.num_episodes
        self.every, self.started_s, self.seed = every, started_s, seed
        self.run_dir, self.steps_per_iteration = Path(run_dir), steps_per_iteration
        self.episode_length_s = eval_episode_length_s(self.task, None)
        self.rank = rank if rank is not None else Rank()
        self.share = eval_share(self.num_episodes, seed, self.rank, blocks=self.layout.blocks)
        """This rank's episodes (all of them in one process)."""
        self.env: envs.RLEnv | None = None
        self.confirm: bool | None = None
        """Whether a success is confirmed on the CPU engine (False when the evaluation env is it);
        None until the env is built (``eval_async.BackgroundEval``: its worker's env)."""
        self.on_cpu_engine: bool | None = None
        """Whether the evaluation env is the CPU engine (None until built, as ``confirm``)."""
        if build_env:
            self._build_env(device, confirm_on_cpu_engine)
        self.eval_device = str(self.env.device) if self.env is not None else None
        """The evaluation env's device, as ``time_to_criterion.json`` names it."""
        self.cpu_env: envs.RLEnv | None = None
        """The CPU-engine evaluation env, built at the first success to confirm."""
        self.eval_s = 0.0
        """Seconds spent evaluating, inside the timed total (reported, not subtracted)."""
        self._csv = self.run_dir / "evals.csv"
        self.reached: dict[str, Any] | None = None
        """The first evaluation that met the criteria (``time_to_criterion.json``), if any yet;
        rank 0's is the run's (the others do not read the resumed run's)."""
        if not self.rank.is_main or not records:
            return  # rank 0 writes the run folder
        if start > 0:
            self.reached = resume_evals(self.run_dir, start)
        if not self._csv.is_file():
            atomic_write_text(self._csv, ",".join(EVAL_COLUMNS) + "\n", fsync=True)

    def due(self, iteration: int) -> bool:
        return eval_due(iteration, self.every)

    def _build_env(self, device: str | None, confirm_on_cpu_engine: bool) -> None:
        self.env = runs.make_env_for_run(self.info, num_envs=self.share.episodes, seed=self.share.seed, play=True,
                                         device=device, episode_length_s=self.episode_length_s,
                                         **self.layout.env_overrides)
        # 100 worlds are launch-bound on a GPU: each evaluation's 1,000 steps replay one CUDA graph
        self.env.use_cuda_graph()
        self.vec_env = RslRlVecEnv(self.env)
        # each evaluation starts the env's generator where a fresh env's stands, so it draws the
        # episodes `ambulo eval` draws for this seed and device
        self._rng_state = self.env.generator.get_state()
        self.on_cpu_engine = is_cpu_engine(self.env)
        self.confirm = confirm_on_cpu_engine and not self.on_cpu_engine

    def poll(self) -> list[tuple[int, dict[str, Any], float]]:
        """Evaluations finished since the last call, as (iteration, result, wall s): none here,
        where ``__call__`` returns its own (``eval_async.BackgroundEval`` returns its worker's)."""
        return []

    def finish(self) -> None:
        """Training ran all its iterations: nothing is left to evaluate here (``eval_async``
        waits for its worker)."""

    def __call__(self, runner, iteration: int) -> dict[str, Any]:
        """Save ``model_<iteration>.pt``, evaluate it (and confirm a success on the CPU engine),
        log it; return the eval result (``result["cpu_engine"]``: the confirmation, if run).
        In a data-parallel run: this rank's share, merged with the others' (see the module doc)."""
        checkpoint = self.run_dir / f"model_{iteration}.pt"
        if self.rank.is_main:
            runner.save(str(checkpoint))
        began = time.monotonic()
        policy = runner.get_inference_policy(device=str(self.env.device))
        try:
            result, met, cpu, confirmed = self.evaluate(policy)
        finally:
            runner.alg.train_mode()  # get_inference_policy switched it to eval mode
        self.eval_s += time.monotonic() - began
        wall_s = time.monotonic() - self.started_s
        if self.rank.is_main:
            self._record(runner, iteration, checkpoint, wall_s, result, met, cpu, confirmed)
        elif confirmed and self.reached is None:
            self.reached = {"iteration": iteration}
        return result

    def evaluate(self, policy, *, cpu_first: bool = False
                 ) -> tuple[dict[str, Any], bool, dict[str, Any] | None, bool]:
        """``policy`` over this evaluation's episodes (and, when they meet the criteria off the
        CPU engine, over the same episodes on it): (result, met, the CPU engine's result or None,
        confirmed). ``result["cpu_engine"]`` holds the confirmation when it ran.

        ``cpu_first`` (``--eval-async``'s worker, which shares the training GPU): when a success
        needs the CPU engine's confirmation, judge there first and run the evaluation env only for
        a policy that meets the criteria on the CPU engine. One that does not is reported by its
        CPU-engine result (``result["eval_engine"] == "cpu"``; met False, cpu None). The verdict is
        the same in either order (both engines must meet); most evaluations fail, so the GPU is
        left to training."""
        if cpu_first and self.confirm:
            cpu = self._cpu_engine_eval(policy)
            if not self._met(cpu):
                return {**cpu, "eval_engine": "cpu"}, False, None, False
            result = self._run(policy)
            met = self._met(result)
            return {**result, "cpu_engine": cpu}, met, cpu, met
        result = self._run(policy)
        met = self._met(result)
        cpu = self._cpu_engine_eval(policy) if met and self.confirm else None
        confirmed = met and (not self.confirm or self._met(cpu))
        if cpu is not None:
            result = {**result, "cpu_engine": cpu}
        return result, met, cpu, confirmed

    def _run(self, policy) -> dict[str, Any]:
        """``policy`` over this evaluation's episodes in the evaluation env."""
        self.env.generator.set_state(self._rng_state)  # the same commands and resets every time
        return run_episodes(self.env, self.vec_env, policy, self.task, blocks=self.layout.run_blocks,
                            **self._merge())

    def _record(self, runner, iteration: int, checkpoint: Path, wall_s: float, result: dict[str, Any],
                met: bool, cpu: dict[str, Any] | None, confirmed: bool) -> None:
        """Rank 0: the evals.csv row, TensorBoard's scalars, and the first success's record."""
        engine = result.get("eval_engine", "training")  # "cpu": the CPU engine's, judged first
        result = {k: v for k, v in result.items() if k not in ("cpu_engine", "eval_engine")}
        row = [iteration, f"{wall_s:.1f}", (iteration + 1) * self.steps_per_iteration,
               f"{result['fall_rate']:.3f}", f"{result['mean_episode_length_s']:.2f}",
               f"{result['mean_return']:.2f}", _metrics_text(result), met,
               "" if cpu is None else f"fall_rate={cpu['fall_rate']:.3f} {_metrics_text(cpu)}",
               "" if cpu is None else self._met(cpu), _worst_block_cell(result),
               "" if cpu is None else _worst_block_cell(cpu), kinds_cell(result), engine]
        line = io.StringIO()
        csv.writer(line).writerow(row)
        with open(self._csv, "a") as f:
            f.write(line.getvalue())
        writer = getattr(runner.logger, "writer", None)
        if writer is not None:
            # a row judged on the CPU engine first has no evaluation-env numbers: its own series
            prefix = "eval_cpu_engine" if engine == "cpu" else "eval"
            for key in ("fall_rate", "mean_episode_length_s", *_metrics(result)):
                writer.add_scalar(f"{prefix}/{key}", result[key], iteration)
            if engine != "cpu":
                writer.add_scalar("eval/criteria_met", float(met), iteration)
            worst = worst_block(result)  # the block the criteria are nearest to failing in, whichever it is
            if worst is not None:
                for key in ("fall_rate", *_metrics(worst)):
                    writer.add_scalar(f"{prefix}/worst_block_{key}", worst[key], iteration)
            for name, kind in result.get("by_kind", {}).items():  # a terrain task's tile kinds, reported
                for key in ("fall_rate", *step_metrics(kind)):
                    writer.add_scalar(f"{prefix}_by_kind/{name}/{key}", kind[key], iteration)
            if cpu is not None:
                for key in ("fall_rate", *_metrics(cpu)):
                    writer.add_scalar(f"eval_cpu_engine/{key}", cpu[key], iteration)
        if confirmed and self.reached is None:
            self.reached = {"criteria": [c.name for c in self.task.criteria], "iteration": iteration,
                            "checkpoint": checkpoint.name, "wall_s": round(wall_s, 1),
                            "env_steps": (iteration + 1) * self.steps_per_iteration,
                            "eval_s_included": round(self.eval_s, 1), "eval": result,
                            "eval_device": self.eval_device,
                            "eval_cpu_engine": cpu if cpu is not None else result if self.on_cpu_engine else None,
                            **self._reached_extras(iteration)}
            atomic_write_json(self.run_dir / TIME_FILE, self.reached, indent=2, fsync=True)

    def _reached_extras(self, iteration: int) -> dict[str, Any]:
        """More fields of ``time_to_criterion.json`` (``eval_async``: when the checkpoint was saved)."""
        return {}

    def _merge(self) -> dict[str, Any]:
        """``run_episodes``' ``merge`` argument in a data-parallel run (nothing in one process):
        every share's totals, gathered on this rank's training device (also for the CPU-engine
        confirmation: NCCL takes GPU tensors only)."""
        if not self.rank.distributed:
            return {}
        return {"merge": lambda sums: merge_over_ranks(sums, self.rank, self.env.device)}

    def _met(self, result: dict[str, Any]) -> bool:
        return all(result[c.name] for c in self.task.criteria)

    def _cpu_engine_eval(self, policy) -> dict[str, Any]:
        """``policy`` (a copy, on the CPU) over the same episodes on the CPU engine."""
        if self.cpu_env is None:
            self.cpu_env = runs.make_env_for_run(self.info, num_envs=self.share.episodes, seed=self.share.seed,
                                                 play=True, device="cpu", engine="mujoco",
                                                 episode_length_s=self.episode_length_s, **self.layout.env_overrides)
            self._cpu_vec_env = RslRlVecEnv(self.cpu_env)
            self._cpu_rng_state = self.cpu_env.generator.get_state()
        self.cpu_env.generator.set_state(self._cpu_rng_state)
        return run_episodes(self.cpu_env, self._cpu_vec_env, CpuPolicy(policy), self.task,
                            blocks=self.layout.run_blocks, **self._merge())

    def close(self) -> None:
        if self.env is not None:
            self.env.close()
        if self.cpu_env is not None:
            self.cpu_env.close()


class CpuPolicy(torch.nn.Module):
    """A copy on the CPU of rsl-rl's ``MLPModel`` ``policy``, acting as ``get_inference_policy``'s
    (the mean action) on the same TensorDict observations. A copy, because ``Module.to`` moves in
    place: the training policy stays on its device."""

    def __init__(self, policy):
        super().__init__()
        self.net = policy.as_jit().to("cpu").eval()  # rsl-rl's export copy: normalizer, MLP, mean
        self.groups = list(policy.obs_groups)

    def forward(self, obs) -> torch.Tensor:
        return self.net(torch.cat([obs[g].to("cpu") for g in self.groups], dim=-1))


def _metrics(result: dict[str, Any]) -> dict[str, float]:
    return {k: round(v, 4) for k, v in result.items() if k.startswith("mean_abs")}


def _metrics_text(result: dict[str, Any]) -> str:
    return " ".join(f"{k}={v}" for k, v in _metrics(result).items())


def metrics_from_text(text: str) -> dict[str, float]:
    """An ``evals.csv`` metrics cell (``metrics``, ``cpu_engine_metrics``: ``name=value`` pairs
    separated by spaces) as a dict; the empty cell of an evaluation not run gives ``{}``."""
    return {name: float(value) for name, value in (pair.split("=", 1) for pair in text.split())}


def _worst_block_cell(result: dict[str, Any]) -> str:
    """``evals.csv``'s ``worst_block`` cell of a blocked evaluation's ``result`` ('' without blocks)."""
    worst = worst_block(result)
    if worst is None:
        return ""
    return (f"{worst['name'].replace(' ', '_')} fall_rate={worst['fall_rate']:.4f} {_metrics_text(worst)} "
            f"blocks_failed={len(result['blocks_failed'])}")


def worst_block_from_text(text: str) -> tuple[str, dict[str, float]] | None:
    """A ``worst_block`` cell as (the block's name, its ``name=value`` pairs); None for the empty
    cell of a task without blocks (or of an evaluation not run)."""
    if not text.strip():
        return None
    name, _, pairs = text.strip().partition(" ")
    return name, metrics_from_text(pairs)


def summary(result: dict[str, Any], iteration: int, wall_s: float) -> str:
    """One line on an evaluation (and its CPU-engine confirmation), for the console."""
    def one(res: dict[str, Any]) -> str:
        metrics = ", ".join(f"{k[len('mean_'):]} {v:.3f}" for k, v in res.items() if k.startswith("mean_abs"))
        met = [c for c in res["criteria"] if res[c]]
        return (f"fall rate {res['fall_rate']:.2f}, {metrics}; "
                f"{'meets ' + ', '.join(met) if met else 'criteria not met'}")

    def one_and_worst(res: dict[str, Any]) -> str:
        worst = [text for text in (worst_block_text(res), most_falls_text(res)) if text]
        return "; ".join([one(res), *worst])

    where = "on the CPU engine (judged there first): " if result.get("eval_engine") == "cpu" else ""
    line = f"eval @ it {iteration} ({wall_s / 60:.1f} min): {where}{one_and_worst(result)}"
    if "cpu_engine" in result:
        line += f"; on the CPU engine: {one_and_worst(result['cpu_engine'])}"
    return line
