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
import shutil
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from ambulo import envs
from ambulo.envs.symmetry import SymmetryError
from ambulo.envs.transfer import PLAY_KEEPS
from ambulo.utils.atomic import atomic_write_json
from ambulo.utils.overrides import replace_dotted

from .checkpoints import (
    CheckpointError,
    RunError,
    atomic_torch_save,
    checkpoints,
    find_checkpoint,
    is_checkpoint_name,
    latest_checkpoint,
    latest_valid_checkpoint,
    read_checkpoint,
)
from .config import PpoCfg

RUN_FILE = "run.json"


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
    (its newest run under ``root`` that saved a checkpoint: a run that stopped before its
    first save is skipped, with a note, so it does not hide the good runs before it)."""
    path = Path(run)
    if path.is_file() and is_checkpoint_name(path.name):
        return path.parent
    if (path / RUN_FILE).is_file():
        return path
    if str(run) in envs.names():
        found = sorted(p for p in (Path(root) / str(run)).glob("*") if (p / RUN_FILE).is_file())
        if not found:
            raise FileNotFoundError(f"no runs of task {str(run)!r} under {root}/; "
                                    f"train one with `ambulo train {run}`")
        saved = [p for p in found if checkpoints(p)]
        if not saved:
            raise FileNotFoundError(f"no run of task {str(run)!r} under {root}/ saved a checkpoint "
                                    f"({len(found)} stopped before their first save); train "
                                    f"one with `ambulo train {run}`")
        skipped = found[found.index(saved[-1]) + 1:]
        if skipped:
            print(f"note: using {saved[-1]}; skipping newer {', '.join(p.name for p in skipped)} "
                  "(no checkpoint: stopped before its first save)", file=sys.stderr)
        return saved[-1]
    raise FileNotFoundError(f"{run!r} is neither a run folder, a checkpoint nor a task name "
                            f"({', '.join(envs.names())})")


def resolve_init_from(source: str | os.PathLike) -> tuple[Path, str]:
    """The checkpoint ``ambulo train --init-from source`` starts from (absolute), and the
    algorithm that trained it (its run's ``run.json``, else the checkpoint's own ``algo`` entry,
    else PPO): ``source`` is a checkpoint file, or a run folder for its newest readable one (as
    ``--resume`` picks). ``CheckpointError`` in one line, before anything is built, when there is
    none. A shipped policy is refused: its folder keeps the exported actor only (TorchScript and
    ONNX with the observation normalizer folded in), no critic and no rsl-rl checkpoint."""
    path = Path(source)
    fix = "pass a model_<iteration>.pt or the run folder `ambulo train` printed"
    if not path.exists():
        if str(source) == "shipped":
            raise CheckpointError("--init-from shipped: a shipped policy keeps only its exported actor "
                                  "(policy.pt/onnx), no critic or rsl-rl checkpoint", fix)
        raise CheckpointError(f"--init-from {source}: no such checkpoint file or run folder", fix)
    try:
        checkpoint = latest_valid_checkpoint(path) if path.is_dir() else path
        saved = read_checkpoint(checkpoint)
    except CheckpointError as err:
        raise CheckpointError(f"cannot init from {source}: {err.problem}", fix) from None
    info = read_run_info(checkpoint.parent) if (checkpoint.parent / RUN_FILE).is_file() else {}
    return checkpoint.resolve(), info.get("algo") or saved.get("algo") or "ppo"


def discard_new_run(run_dir: Path) -> None:
    """Remove the run folder this process just made for a run refused before its first
    iteration (``--init-from`` weights that do not fit, symmetry asked of a task that cannot be
    mirrored): it holds only run.json and empty logs."""
    shutil.rmtree(run_dir, ignore_errors=True)
    with contextlib.suppress(OSError):  # and the task's folder, if this run was its first
        Path(run_dir).parent.rmdir()


@contextlib.contextmanager
def refused_before_training(run_dir: Path, *closers: Callable[[], None], discard: bool = True) -> Iterator[None]:
    """Within the block, a refusal of the run as configured (``CheckpointError``: ``--init-from``
    weights of other shapes; ``SymmetryError``: symmetry asked of a task that cannot be mirrored)
    calls ``closers`` (the env, a log writer) and, with ``discard`` (a new run, made by this
    process), removes its folder (``discard_new_run``) before the error goes on: nothing is left."""
    try:
        yield
    except (CheckpointError, SymmetryError):
        for close in closers:
            close()
        if discard:
            discard_new_run(run_dir)
        raise


def note_kept_settings(info: dict[str, Any], **given: Any) -> None:
    """One line when a resume was given settings that differ from the run's: a resumed run
    keeps its run.json (its networks, batch and RNG streams continue), as --env-cfg does.
    ``num_envs`` is the learner's (the ``ppo`` or ``offpolicy`` section, by ``algo``)."""
    learner = info["ppo"] if info.get("algo", "ppo") == "ppo" else info["offpolicy"]
    kept = {"num_envs": learner["num_envs"], "seed": info["seed"], "device": info["device"]}
    differ = {k: v for k, v in given.items() if v is not None and v != kept[k]}
    if differ:
        asked = ", ".join(f"{k} {v}" for k, v in differ.items())
        theirs = ", ".join(f"{k} {kept[k]}" for k in differ)
        print(f"resume keeps the run's {theirs} (run.json), not {asked}; start a new run to "
              "change them")


def play_overrides(task: str, env_overrides: dict[str, Any]) -> dict[str, Any]:
    """The training overrides ``env_overrides`` that a play env of ``task`` takes: not those of a
    setting the play variant sets itself (its value there differs from the training default:
    pushes, noise, friction and mass ranges, the episode length, humanoid-rough's terrain levels;
    or its field is marked ``envs.transfer.PLAY_KEEPS``: ``transfer``). So a run trained with
    ``--env-cfg transfer.com_offset_m=0.05`` or ``friction_range=...`` is evaluated, played and
    confirmed on the CPU engine nominal, as ``ambulo eval`` defines it, while an override the
    policy depends on (``action_scale``, ``terrain.spacing_m``, the command ranges) carries over."""
    spec = envs.spec(task)
    train, play = spec.cfg_fn(), spec.play_cfg()
    marked = {f.name for f in dataclasses.fields(play) if f.metadata.get(PLAY_KEEPS)}
    return {k: v for k, v in env_overrides.items()
            if k.split(".")[0] not in marked and _setting(play, k) == _setting(train, k)}


def _setting(cfg: Any, key: str) -> Any:
    """The value at dotted ``key`` of config ``cfg`` (dataclass fields, dict entries; None when a
    dict has no such entry)."""
    for part in key.split("."):
        cfg = cfg.get(part) if isinstance(cfg, dict) else getattr(cfg, part)
    return cfg


def make_env_for_run(info: dict[str, Any], *, num_envs: int, seed: int | None = None,
                     device: str | None = None, play: bool = False, user_overrides: dict[str, Any] | None = None,
                     **overrides: Any) -> envs.RLEnv:
    """The run's task env with its training overrides, resized to ``num_envs``; ``play``
    starts from the task's play variant (no pushes, observation noise or transfer
    randomization), with the training overrides ``play_overrides`` keeps. ``overrides`` (the
    caller's: an evaluation's episode length, the robustness table's ``transfer``; None: not
    set) apply next, then ``user_overrides`` (``ambulo eval --env-cfg``: dotted keys, None a value)."""
    env_overrides = dict(info.get("env_overrides", {}))
    if play:
        env_overrides = play_overrides(info["task"], env_overrides)
    env_overrides.update({k: v for k, v in overrides.items() if v is not None})
    env_overrides.update(user_overrides or {})
    return envs.make(info["task"], num_envs=num_envs, device=device or info["device"],
                     seed=info["seed"] if seed is None else seed, play=play, **env_overrides)


def ppo_from_info(info: dict[str, Any]) -> PpoCfg:
    """The run's PPO settings (JSON lists become the tuples ``PpoCfg`` declares)."""
    fields = {f.name for f in dataclasses.fields(PpoCfg)}
    return replace_dotted(PpoCfg(), {k: v for k, v in info["ppo"].items() if k in fields}, check_types=True)


def resolve_policy(run: str | os.PathLike, checkpoint: str | os.PathLike | None = None,
                   root: str | os.PathLike = "runs") -> tuple[Path, Path]:
    """The run folder and checkpoint that play/eval/export load, checked before any env is
    built: ``run`` as ``resolve_run`` takes it, ``checkpoint`` as ``find_checkpoint`` does
    (``None``: the checkpoint ``run`` names if it is one, else the newest readable)."""
    run_dir = resolve_run(run, root)
    if checkpoint is None and Path(run).is_file():
        checkpoint = run
    return run_dir, find_checkpoint(run_dir, checkpoint)


def load_runner(run_dir: Path, env: envs.RLEnv, checkpoint: Path):
    """An ``OnPolicyRunner`` on ``env`` with the run's networks and the weights of
    ``checkpoint`` (from ``resolve_policy``), without logging; for an off-policy run, its
    ``offpolicy.OffPolicyRunner`` (the same ``env``, ``get_inference_policy``)."""
    from rsl_rl.runners import OnPolicyRunner

    from .vecenv import RslRlVecEnv

    info = read_run_info(run_dir)
    if info.get("algo", "ppo") != "ppo":  # fast-sac / fast-td3: their actor, the same interface
        from .offpolicy import load_runner as load_offpolicy_runner

        return load_offpolicy_runner(info, env, checkpoint)
    ppo = ppo_from_info(info)
    with contextlib.redirect_stdout(io.StringIO()):  # rsl-rl prints the networks
        runner = OnPolicyRunner(RslRlVecEnv(env), ppo.to_rsl_rl(env.num_privileged_obs > 0),
                                log_dir=None, device=str(env.device))
    runner.load(str(checkpoint), map_location=str(env.device))
    return runner


__all__ = ["RUN_FILE", "CheckpointError", "RunError", "atomic_torch_save", "checkpoints",
           "discard_new_run", "find_checkpoint", "latest_checkpoint", "latest_valid_checkpoint", "load_runner",
           "make_env_for_run", "new_run_dir", "play_overrides", "ppo_from_info", "read_run_info",
           "refused_before_training",
           "resolve_init_from", "resolve_policy", "resolve_run", "write_run_info"]
