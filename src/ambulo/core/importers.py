"""Read MJCF, URDF and UsdPhysics USD files into an ``MjSpec`` ready to attach.

Every importer returns a spec whose element names are relative to the file's
"default prim" (MJCF/URDF: the world body; USD: the stage's default prim), so that
``add_reference_to_stage(path, "/World/Robot")`` can prefix them with the prim path.
Every hinge/slide joint leaves with one drive actuator in ambulo's convention
(see ``drives.py``), as Isaac's URDF importer adds joint drives.
"""

from __future__ import annotations

import math
import os
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco

from .drives import DriveDefaults, add_drive, ensure_drives
from .packages import resolve_package_uri

_USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")


class AssetError(ValueError):
    """A robot/scene file is missing, of an unknown kind, or malformed."""


def load_spec(path: str | os.PathLike, *, drives: DriveDefaults | None = None,
              fixed_base: bool | None = None) -> mujoco.MjSpec:
    """Load ``path`` (MJCF ``.xml``, URDF ``.urdf``, USD ``.usd*``) as a spec with drives."""
    """``fixed_base``: weld the root to the world (URDF: no free joint is added; MJCF/USD: the
    root's free joint is removed); None/False keeps a floating base."""
    file = Path(path).expanduser()
    if not file.is_file():
        raise AssetError(
            f"file not found: {str(path)!r}. Check the path (relative paths are "
            f"resolved from {os.getcwd()!r}) or use ambulo.assets.path(name) for a bundled robot."
        )
    suffix = file.suffix.lower()
    if suffix == ".urdf" or (suffix == ".xml" and _root_tag(file) == "robot"):
        spec = _load_urdf(file, fixed_base=bool(fixed_base))
    elif suffix in _USD_SUFFIXES:
        spec = _load_usd(file)
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
    """Build a spec and compile it once, turning MuJoCo's errors into AssetError."""
    try:
        spec = make()
        spec.compile()
    except (ValueError, mujoco.FatalError) as err:
        raise AssetError(f"{file}: cannot be loaded: {err}") from None
    return spec


def _load_urdf(file: Path, fixed_base: bool) -> mujoco.MjSpec:
    try:
        tree = ET.parse(file)
    except ET.ParseError as err:
        raise AssetError(f"{file}: malformed URDF XML ({err}); fix the file or re-export it.") from None
    robot = tree.getroot()
    if robot.tag != "robot":
        raise AssetError(f"{file}: a URDF's root element must be <robot>, found <{robot.tag}>.")
    # meshes: package:// against the package path, relative paths against the file
    for mesh in robot.iter("mesh"):
        uri = mesh.get("filename", "")
        mesh.set("filename", _resolve_mesh(uri, file))
    efforts = {
        joint.get("name"): float(limit.get("effort"))
        for joint in robot.iter("joint")
        if (limit := joint.find("limit")) is not None and limit.get("effort")
    }
    # keep every link as its own body (Isaac keeps links as prims) and keep visuals
    robot.insert(0, ET.fromstring(
        '<mujoco><compiler fusestatic="false" discardvisual="false" strippath="false" '
        'balanceinertia="true"/></mujoco>'))
    xml = ET.tostring(robot, encoding="unicode")
    spec = _compile_checked(file, lambda: mujoco.MjSpec.from_string(xml))
    root = spec.worldbody.first_body()
    if root is None:
        raise AssetError(f"{file}: the URDF has no links.")
    if not fixed_base:
        root.add_freejoint(name="root_joint")
    for name, effort in efforts.items():
        joint = spec.joint(name) if name else None
        if joint is not None and effort > 0:
            joint.actfrcrange = [-effort, effort]
            joint.actfrclimited = mujoco.mjtLimited.mjLIMITED_TRUE
    return spec


def _resolve_mesh(uri: str, urdf_file: Path) -> str:
    if uri.startswith("package://"):
        return resolve_package_uri(uri, start=urdf_file)
    if uri.startswith("file://"):
        uri = uri[len("file://"):]
    path = Path(uri)
    if not path.is_absolute():
        path = urdf_file.parent / path
    if not path.is_file():
        raise AssetError(
            f"{urdf_file.name}: mesh {uri!r} not found at {path}; meshes resolve "
            f"relative to the URDF file."
        )
    return str(path)


def _load_usd(file: Path) -> mujoco.MjSpec:
    try:
        from pxr import Usd  # noqa: PLC0415 - only USD needs pxr
    except ImportError:
        raise AssetError("reading USD needs pxr: pip install 'mujoco[usd]'") from None
    try:
        stage = Usd.Stage.Open(str(file))
    except Exception as err:  # pxr raises its own Tf.ErrorException
        first = str(err).strip().splitlines()[-1] if str(err).strip() else ""
        raise AssetError(f"{file}: not a readable USD stage ({first.strip()}); fix or re-export it.") from None
    if stage is None:
        raise AssetError(f"{file}: not a readable USD stage.")
    default = stage.GetDefaultPrim()
    spec = _compile_checked(file, lambda: mujoco.MjSpec.from_file(str(file)))
    # MuJoCo names USD elements by prim path; re-root them at the default prim so
    # the referencing prim path replaces it, as a USD reference does.
    root = str(default.GetPath()) if default else ""

    def relative(path: str) -> str:
        return path[len(root) + 1:] if path.startswith(root + "/") else path.lstrip("/")

    for element in _named_elements(spec):
        element.name = relative(element.name)
    _add_usd_drives(stage, spec, relative, file)
    return spec


def _add_usd_drives(stage, spec: mujoco.MjSpec, relative, file: Path) -> None:
    """Turn UsdPhysics DriveAPI gains into ambulo drives (MuJoCo's importer skips them).

    UsdPhysics states angular drive gains per degree; ambulo's are per radian.
    """
    from pxr import UsdPhysics  # noqa: PLC0415

    per_rad = 180.0 / math.pi
    for prim in stage.Traverse():
        if not prim.IsA(UsdPhysics.Joint):
            continue
        joint = spec.joint(relative(str(prim.GetPath())))
        if joint is None:
            body0 = UsdPhysics.Joint(prim).GetBody0Rel().GetTargets()
            warnings.warn(
                f"{file.name}: joint {prim.GetPath()} was not imported (MuJoCo's USD importer "
                f"drops joints whose body0 {[str(b) for b in body0]} is not a rigid body); leave "
                "body0 empty to attach a link to the world", stacklevel=3)
            continue
        for kind in ("angular", "linear"):
            drive = UsdPhysics.DriveAPI.Get(prim, kind)
            if not drive or not prim.HasAPI(UsdPhysics.DriveAPI, kind):
                continue
            scale = per_rad if kind == "angular" else 1.0
            kp = float(drive.GetStiffnessAttr().Get() or 0.0) * scale
            kd = float(drive.GetDampingAttr().Get() or 0.0) * scale
            max_force = drive.GetMaxForceAttr().Get()
            limited = max_force is not None and math.isfinite(max_force) and max_force > 0
            add_drive(spec, joint.name, kp, kd, max_force if limited else None)


def _named_elements(spec: mujoco.MjSpec):
    for group in (spec.bodies, spec.geoms, spec.joints, spec.sites, spec.cameras,
                  spec.lights, spec.actuators, spec.sensors, spec.tendons):
        for element in group:
            if element.name:
                yield element
