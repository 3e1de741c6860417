"""Run directories, checkpoints and loading a trained policy back.

A run lives in ``<root>/<task>/<YYYY-mm-dd_HH-MM-SS>/`` and holds ``run.json`` (what was
trained, so play/export/eval rebuild the same env and networks), ``model_<it>.pt``
checkpoints, TensorBoard event files, ``metrics.csv`` and, after export, ``exported/``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import io
import json
import os
import re
from pathlib import Path
from typing import Any

import torch

from ambulo import envs

from ambulo.utils.atomic import atomic_open, atomic_write_json
from ambulo.utils.overrides import replace_dotted

from .config import PpoCfg

RUN_FILE = "run.json"
_CHECKPOINT = re.compile(r"^model_(\d+)\.pt$")


def new_run_dir(task: str, root: str | os.PathLike = "runs") -> Path:
    """A new, empty run directory for ``task`` named by the current time."""
    stamp = datetime.datetime.now().strftime("%Y-%m-%d_%H-%M-%S")
    path = Path(root) / task / stamp
    suffix = 1
    while path.exists():  # two runs started within one second
        path = Path(root) / task / f"{stamp}_{suffix}"
        suffix += 1
    path.mkdir(parents=True)
    return path


def write_run_info(run_dir: Path, info: dict[str, Any]) -> None:
    atomic_write_json(run_dir / RUN_FILE, info, indent=2, fsync=True)


def read_run_info(run_dir: Path) -> dict[str, Any]:
    file = Path(run_dir) / RUN_FILE
    if not file.is_file():
        raise FileNotFoundError(f"{run_dir} is not an ambulo run (no {RUN_FILE}); "
                                "pass the folder `ambulo train` printed")
    return json.loads(file.read_text())


def resolve_run(run: str | os.PathLike, root: str | os.PathLike = "runs") -> Path:
    """The run directory named by ``run``: a run folder, a checkpoint in one, or a task name
    (its latest run under ``root``)."""
    path = Path(run)
    if path.is_file() and _CHECKPOINT.match(path.name):
        return path.parent
    if (path / RUN_FILE).is_file():
        return path
    if str(run) in envs.names():
        runs = sorted(p for p in (Path(root) / str(run)).glob("*") if (p / RUN_FILE).is_file())
        if not runs:
            raise FileNotFoundError(f"no runs of task {str(run)!r} under {root}/; "
                                    f"train one with `ambulo train {run}`")
        return runs[-1]
    raise FileNotFoundError(f"{run!r} is neither a run folder, a checkpoint nor a task name "
                            f"({', '.join(envs.names())})")


def checkpoints(run_dir: Path) -> list[tuple[int, Path]]:
    """``(iteration, path)`` of the run's complete checkpoints, oldest first."""
    found = []
    for path in Path(run_dir).iterdir():
        match = _CHECKPOINT.match(path.name)
        if match:
            found.append((int(match.group(1)), path))
    return sorted(found)


def latest_checkpoint(run_dir: Path) -> Path:
    found = checkpoints(run_dir)
    if not found:
        raise FileNotFoundError(f"run {run_dir} has no checkpoint (model_<iteration>.pt) yet")
    return found[-1][1]


def atomic_torch_save(obj: Any, path: Path) -> None:
    """``torch.save`` through a temporary file, fsync and ``os.replace``: a crash never leaves
    a truncated checkpoint under the final name."""
    with atomic_open(path, fsync=True) as f:
        torch.save(obj, f)


def make_env_for_run(info: dict[str, Any], *, num_envs: int, seed: int | None = None,
                     device: str | None = None, play: bool = False, **overrides: Any) -> envs.RLEnv:
    """The run's task env with its training overrides, resized to ``num_envs``; ``play``
    starts from the task's play variant (no pushes or observation noise)."""
    env_overrides = dict(info.get("env_overrides", {}))
    env_overrides.update({k: v for k, v in overrides.items() if v is not None})
    return envs.make(info["task"], num_envs=num_envs, device=device or info["device"],
                     seed=info["seed"] if seed is None else seed, play=play, **env_overrides)


def ppo_from_info(info: dict[str, Any]) -> PpoCfg:
    """The run's PPO settings (JSON lists become the tuples ``PpoCfg`` declares)."""
    fields = {f.name for f in dataclasses.fields(PpoCfg)}
    return replace_dotted(PpoCfg(), {k: v for k, v in info["ppo"].items() if k in fields}, check_types=True)


def load_runner(run_dir: Path, env: envs.RLEnv, checkpoint: str | os.PathLike | None = None):
    """An ``OnPolicyRunner`` on ``env`` with the run's networks and weights (no logging)."""
    from rsl_rl.runners import OnPolicyRunner  # noqa: PLC0415

    from .vecenv import RslRlVecEnv  # noqa: PLC0415

    info = read_run_info(run_dir)
    ppo = ppo_from_info(info)
    with contextlib.redirect_stdout(io.StringIO()):  # rsl-rl prints the networks
        runner = OnPolicyRunner(RslRlVecEnv(env), ppo.to_rsl_rl(env.num_privileged_obs > 0),
                                log_dir=None, device=str(env.device))
    path = Path(checkpoint) if checkpoint else latest_checkpoint(run_dir)
    runner.load(str(path), map_location=str(env.device))
    return runner, path
