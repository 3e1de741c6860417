"""Load a repository script (an example, a benchmark, a tool under ``scripts/``) as a module, for the
tests that run one: scripts are files, not packages, so they are imported by path."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]
"""The repository root."""


def load_script(path: Path, name: str | None = None, register: bool = False) -> ModuleType:
    """Import the script at ``path`` as module ``name`` (default: its file name). ``register``: put it in
    ``sys.modules`` first, which dataclasses defined in it need (they look their module up there)."""
    path = Path(path)
    spec = importlib.util.spec_from_file_location(name or f"script_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    if register:
        sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def run_main(path: Path, *argv: str):
    """Run a script's ``main(argv)`` and return what it returns."""
    return load_script(path).main(list(argv))


def printed_number(out: str, before: str, after: str) -> float:
    """The number a script printed between ``before`` and ``after`` on the first line holding ``before``."""
    line = next(line for line in out.splitlines() if before in line)
    return float(line.split(before, 1)[1].split(after, 1)[0])
