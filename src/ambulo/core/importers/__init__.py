"""Read MJCF, URDF and UsdPhysics USD files into an ``MjSpec`` ready to attach.

Every importer returns a spec whose element names are relative to the file's
"default prim" (MJCF/URDF: the world body; USD: the stage's default prim), so that
``add_reference_to_stage(path, "/World/Robot")`` can prefix them with the prim path.
Every hinge/slide joint leaves with one drive actuator in ambulo's convention
(``core/drives.py``), as Isaac's URDF importer adds joint drives.

The package: ``load_spec`` here picks the reader by suffix; ``urdf`` and ``usd`` are the URDF and
USD readers; ``meshes`` converts meshes MuJoCo cannot decode; ``inertia`` repairs a URDF's
inertias; ``packages`` resolves ``package://`` URIs; ``xml_lines`` keeps source line numbers for
error messages; ``asset_errors`` holds the one-line errors they raise.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco

from ..drives import DriveDefaults, ensure_drives
from .asset_errors import AssetError, AssetNotFoundError, MeshConversionError
from .urdf import load_urdf
from .usd import load_usd

_USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")
_ROBOT_SUFFIXES = (".urdf", ".xml") + _USD_SUFFIXES


def load_spec(path: str | os.PathLike, *, drives: DriveDefaults | None = None,
              fixed_base: bool | None = None) -> mujoco.MjSpec:
    """Load ``path`` (MJCF ``.xml``, URDF ``.urdf``, USD ``.usd*``) as a spec with drives.

    ``fixed_base``: weld the root to the world (URDF: no free joint is added; MJCF/USD: the
    root's free joint is removed); None/False keeps a floating base."""
    file = Path(path).expanduser()
    if file.is_dir():
        inside = sorted(p.name for p in file.iterdir() if p.suffix.lower() in _ROBOT_SUFFIXES)[:5]
        hint = f" (it holds {', '.join(inside)})" if inside else ""
        raise AssetError(f"{str(path)!r} is a folder, not a file; pass the robot file inside it{hint}.")
    if not file.is_file():
        raise AssetNotFoundError(
            f"file not found: {str(path)!r}. Check the path (relative paths are "
            f"resolved from {os.getcwd()!r}) or use ambulo.assets.path(name) for a bundled robot."
        )
    suffix = file.suffix.lower()
    if suffix == ".urdf" or (suffix == ".xml" and _root_tag(file) == "robot"):
        spec = load_urdf(file, fixed_base=bool(fixed_base))
    elif suffix in _USD_SUFFIXES:
        spec = load_usd(file)
    elif suffix == ".xml":
        spec = _compile_checked(file, lambda: mujoco.MjSpec.from_file(str(file)))
    else:
        raise AssetError(
            f"{file.name}: unknown file kind {suffix!r}; ambulo reads MJCF (.xml), "
            f"URDF (.urdf) and USD ({', '.join(_USD_SUFFIXES)})."
        )
    if fixed_base and suffix != ".urdf":
        _weld_root(spec, file)
    ensure_drives(spec, drives or DriveDefaults())
    return spec


def _weld_root(spec: mujoco.MjSpec, file: Path) -> None:
    """Remove the root body's free joint: the robot hangs from the world where placed."""
    root = spec.worldbody.first_body()
    free = [j for j in (root.joints if root is not None else [])
            if j.type == mujoco.mjtJoint.mjJNT_FREE]
    if not free:
        raise AssetError(f"{file.name}: fixed_base=True but its root body has no free joint to remove")
    for joint in free:
        spec.delete(joint)


def _root_tag(file: Path) -> str:
    try:
        for _, elem in ET.iterparse(file, events=("start",)):
            return elem.tag
    except ET.ParseError as err:
        raise AssetError(f"{file}: malformed XML ({err}); fix the file or re-export it.") from None
    return ""


def _compile_checked(file: Path, make) -> mujoco.MjSpec:
    """Build a spec and compile it once, turning MuJoCo's errors into AssetError.

    MJCF is read by MuJoCo from the file itself, so its "line N" is the user's line."""
    try:
        spec = make()
        spec.compile()
    except (ValueError, mujoco.FatalError) as err:
        text = "; ".join(line.strip() for line in str(err).splitlines() if line.strip())
        raise AssetError(f"{file}: cannot be loaded: {text}") from None
    return spec


__all__ = ["AssetError", "AssetNotFoundError", "MeshConversionError", "load_spec"]
