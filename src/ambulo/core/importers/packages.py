"""Resolve ``package://name/rel/path`` URIs as ROS tools do, without ROS installed.

The search path is, in order: ``AMBULO_PACKAGE_PATH`` and ``ROS_PACKAGE_PATH``
(os.pathsep-separated folders that contain packages), the ``share/`` folders of
pip packages installed with cmeel (``example-robot-data`` installs its robots under
``site-packages/cmeel.prefix/share/example-robot-data``), and the ancestors of the
file that holds the URI (a package checked out next to its URDF).
"""

from __future__ import annotations

import os
import site
import sys
from pathlib import Path


def package_search_path() -> list[Path]:
    """Folders searched for ``package://`` names, in order."""
    folders: list[Path] = []
    for var in ("AMBULO_PACKAGE_PATH", "ROS_PACKAGE_PATH"):
        folders += [Path(p) for p in os.environ.get(var, "").split(os.pathsep) if p]
    prefixes = list(site.getsitepackages()) + [site.getusersitepackages()] + sys.path
    for prefix in dict.fromkeys(prefixes):
        share = Path(prefix) / "cmeel.prefix" / "share"
        if share.is_dir():
            folders.append(share)
    return folders


def resolve_package_uri(uri: str, start: Path | None = None) -> str:
    """Absolute path of ``package://pkg/rel``; raises FileNotFoundError naming the fix."""
    rest = uri[len("package://"):]
    package, _, relative = rest.partition("/")
    candidates = [folder / package for folder in package_search_path()]
    if start is not None:
        # a URDF inside its own package: <pkg>/urdf/robot.urdf
        candidates += [parent for parent in Path(start).resolve().parents if parent.name == package]
    for root in candidates:
        path = root / relative
        if path.is_file():
            return str(path)
    searched = ", ".join(str(c) for c in candidates) or "(nothing)"
    raise FileNotFoundError(
        f"cannot resolve {uri!r}: package {package!r} is not on the package path "
        f"(searched {searched}). Add the folder containing {package!r} to "
        f"AMBULO_PACKAGE_PATH or ROS_PACKAGE_PATH, or pip install the package that ships it."
    )
