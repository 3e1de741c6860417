"""Bundled robot and scene models (MJCF written for ambulo) and where to find them.

``path("jetbot")`` is the file of a bundled asset; ``get_assets_root_path()`` is the
folder that holds them, so Isaac-style ``assets_root + "/jetbot.xml"`` works too.
"""

from __future__ import annotations

import difflib
from pathlib import Path

_DATA = Path(__file__).resolve().parent / "data"


def get_assets_root_path() -> str:
    """Folder of the bundled assets (Isaac Sim's ``get_assets_root_path``)."""
    return str(_DATA)


POLICIES_DIR = _DATA / "policies"
"""One folder per shipped policy, named after its task with '_' for '-' (``policy_folder``)."""


def policy_folder(task: str) -> Path:
    """Where the shipped policy of ``task`` lives (whether or not one ships): the one statement of
    the folder convention, for ``policies.shipped`` and ``robots`` (which sits below ``policies``)."""
    return POLICIES_DIR / task.replace("-", "_")


_SUFFIXES = (".xml", ".urdf")


def names() -> list[str]:
    """Names of the bundled assets (MJCF ``.xml`` and URDF ``.urdf`` files)."""
    return sorted(p.stem for p in _DATA.iterdir() if p.suffix in _SUFFIXES)


def path(name: str) -> str:
    """File of bundled asset ``name`` (e.g. ``"jetbot"``, ``"humanoid"``, ``"cartpole"``)."""
    file = next((_DATA / f"{name}{s}" for s in _SUFFIXES if (_DATA / f"{name}{s}").is_file()), None)
    if file is None:
        close = difflib.get_close_matches(name, names(), n=3)
        hint = f" Did you mean {', '.join(map(repr, close))}?" if close else ""
        raise FileNotFoundError(
            f"no bundled asset named {name!r}.{hint} Bundled: {', '.join(names())}."
        )
    return str(file)


__all__ = ["POLICIES_DIR", "get_assets_root_path", "names", "path", "policy_folder"]
