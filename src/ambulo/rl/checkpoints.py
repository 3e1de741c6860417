"""A run's checkpoints: naming one, finding the newest readable one, saving one atomically.

Checkpoints are ``model_<iteration>.pt`` in the run folder, written through a temporary file
and ``os.replace`` so a killed run never leaves a truncated file under that name. A file can
still be damaged afterwards (a full disk while copying a run, a partial download), so
readers check it: a corrupt newest checkpoint is named in a warning and the next older one
is used, rather than a traceback from deep inside ``torch.load``.
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path
from typing import Any

import torch

from ambulo.utils.atomic import atomic_open

_CHECKPOINT = re.compile(r"^model_(\d+)\.pt$")


class RunError(Exception):
    """A run or checkpoint that cannot be used as asked: ``problem`` says what is wrong, ``fix``
    what to do (the CLI prints both on one line)."""

    def __init__(self, problem: str, fix: str = ""):
        self.problem, self.fix = problem, fix
        super().__init__(f"{problem}; {fix}" if fix else problem)


class CheckpointError(RunError):
    """A named checkpoint is missing or unreadable, or a run has no readable one."""


def is_checkpoint_name(name: str) -> bool:
    return _CHECKPOINT.match(name) is not None


def checkpoints(run_dir: Path) -> list[tuple[int, Path]]:
    """``(iteration, path)`` of the run's checkpoint files, oldest first (not yet checked for
    damage: see ``read_checkpoint``)."""
    found = []
    for path in Path(run_dir).iterdir():
        match = _CHECKPOINT.match(path.name)
        if match and path.is_file():
            found.append((int(match.group(1)), path))
    return sorted(found)


def latest_checkpoint(run_dir: Path) -> Path:
    """The newest checkpoint file of the run, readable or not."""
    found = checkpoints(run_dir)
    if not found:
        raise CheckpointError(f"run {run_dir} has no checkpoint (model_<iteration>.pt): it "
                              "stopped before its first save", "train it again")
    return found[-1][1]


def read_checkpoint(path: Path) -> dict[str, Any]:
    """The checkpoint's content; ``CheckpointError`` naming the file if it is truncated, corrupt
    or not an rsl-rl checkpoint."""
    try:
        saved = torch.load(path, weights_only=False, map_location="cpu")
    except Exception as err:  # zip, pickle and EOF errors all mean "damaged"
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise CheckpointError(f"checkpoint {path} is unreadable (truncated or corrupt: {reason})",
                              "use another with --checkpoint, or delete it") from None
    if not isinstance(saved, dict) or "iter" not in saved:
        raise CheckpointError(f"{path} is not an rsl-rl checkpoint (no 'iter' entry)",
                              "use a model_<iteration>.pt written by `ambulo train`")
    return saved


def latest_valid_checkpoint(run_dir: Path) -> Path:
    """The newest checkpoint of the run that loads; each damaged newer one is named in a
    one-line warning on stderr. ``CheckpointError`` if there is none, or none loads."""
    found = checkpoints(run_dir)
    if not found:
        latest_checkpoint(run_dir)  # raises the "no checkpoint yet" error
    damaged: list[CheckpointError] = []
    for _, path in reversed(found):
        try:
            read_checkpoint(path)
        except CheckpointError as err:
            damaged.append(err)
            continue
        for err in damaged:
            print(f"warning: {err.problem}; using {path.name}", file=sys.stderr)
        return path
    names = ", ".join(p.name for _, p in found)
    raise CheckpointError(f"no readable checkpoint in {run_dir} ({names}: truncated or corrupt)",
                          "start a new run with `ambulo train <task>`")


def find_checkpoint(run_dir: Path, name: str | os.PathLike | None) -> Path:
    """The checkpoint ``name`` of the run: ``None`` for the newest readable one, else
    ``model_50.pt``, ``50`` or a path, looked up in the run folder first. The named file must
    load (``CheckpointError`` otherwise, with the run's checkpoints as the fix)."""
    if name is None:
        return latest_valid_checkpoint(run_dir)
    text = str(name)
    candidates = [Path(run_dir) / f"model_{text}.pt"] if text.isdigit() else []
    candidates += [Path(run_dir) / text, Path(text)]
    path = next((p for p in candidates if p.is_file()), None)
    if path is None:
        names = [p.name for _, p in checkpoints(run_dir)]
        fix = (f"{run_dir} has {', '.join(names)}" if names else f"{run_dir} has none yet")
        raise CheckpointError(f"checkpoint {text!r} not found", f"{fix}; or leave --checkpoint "
                              "out for the newest")
    read_checkpoint(path)
    return path


def check_same_shapes(checkpoint: Path, saved: dict[str, dict], here: dict[str, dict], task: str) -> None:
    """``CheckpointError`` naming the tensors whose shapes differ (or that only one side has)
    between ``saved``, the checkpoint's state dicts by network (``{"actor_state_dict": ...}``),
    and ``here``, those of the networks ``task`` builds as configured: the observation or action
    sizes, or the hidden sizes, differ. Checked before ``load_state_dict``, whose own error is a
    multi-line traceback."""
    differ = []
    for net, ours in here.items():
        theirs = saved.get(net) or {}
        for key in [*ours, *(k for k in theirs if k not in ours)]:  # the networks' order: input layer first
            shapes = [("x".join(map(str, d[key].shape)) or "scalar") if key in d else "absent" for d in (theirs, ours)]
            if shapes[0] != shapes[1]:
                differ.append(f"{net.removesuffix('_state_dict')}.{key} is {shapes[0]} in it, {shapes[1]} here")
    if differ:
        more = f" and {len(differ) - 3} more" if len(differ) > 3 else ""
        raise CheckpointError(f"the networks of {checkpoint} do not match task {task}'s: "
                              f"{', '.join(differ[:3])}{more}",
                              "init from a run with the same observation, action and hidden sizes (or drop "
                              "the --env-cfg, --ppo-cfg or --algo-cfg settings that change them)")


def atomic_torch_save(obj: Any, path: Path) -> None:
    """``torch.save`` through a temporary file, fsync and ``os.replace``: a crash never leaves
    a truncated checkpoint under the final name."""
    with atomic_open(path, fsync=True) as f:
        torch.save(obj, f)
