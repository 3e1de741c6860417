"""Read a UsdPhysics USD stage into an ``MjSpec`` with MuJoCo's USD importer, saying what it drops.

MuJoCo names USD elements by prim path; the spec is re-rooted at the stage's default prim so
that the referencing prim path replaces it, as a USD reference does. A stage without a
default prim falls back to its only root prim (with a warning); with several root prims, or
a default prim naming nothing, it is an error naming the fix. MuJoCo's importer drops joints
it cannot express (spherical, distance and D6 joints; joints without a rigid body1, with a
body0 that is not a rigid body, or excluded from the articulation): one warning lists them
with the reason. DriveAPI gains, which the importer skips, become ambulo drives, and PhysX's
``physx*:`` attributes are honoured where MuJoCo has a meaning (``usd_physx``). Joints with
``physics:jointEnabled = false`` are left out: as in PhysX, their bodies are not connected by
them.
"""

from __future__ import annotations

import math
import re
import tempfile
import warnings
from pathlib import Path

import mujoco

from ..drives import add_drive
from ..usd_physx import apply_physx
from .asset_errors import AssetError

_PER_RAD = 180.0 / math.pi
"""UsdPhysics states angular drive gains and limits per degree; ambulo's are per radian."""


def load_usd(file: Path) -> mujoco.MjSpec:
    try:
        from pxr import Usd  # only USD needs pxr
    except ImportError:
        raise AssetError("reading USD needs pxr: pip install 'mujoco[usd]'") from None
    try:
        stage = Usd.Stage.Open(str(file))
    except Exception as err:  # pxr raises its own Tf.ErrorException
        raise AssetError(f"{_pxr_problem(str(err), file)}; fix or re-export the stage.") from None
    if stage is None:
        raise AssetError(f"{file}: not a readable USD stage.")
    root = _default_prim_path(stage, file)
    _check_limits(stage, file)
    try:
        with tempfile.TemporaryDirectory(prefix="ambulo-usd-") as folder:
            spec = mujoco.MjSpec.from_file(_without_disabled_joints(stage, file, Path(folder)))
            model = spec.compile()
    except (ValueError, mujoco.FatalError) as err:
        text = "; ".join(line.strip() for line in str(err).splitlines() if line.strip())
        raise AssetError(f"{file}: cannot be loaded: {text}") from None

    def relative(path: str) -> str:
        return path[len(root) + 1:] if root and path.startswith(root + "/") else path.lstrip("/")

    for element in _named_elements(spec):
        element.name = relative(element.name)
    _warn_dropped_joints(stage, spec, relative, file)
    _add_drives(stage, spec, relative)
    apply_physx(stage, spec, model, relative, file.name)
    return spec


def _disabled(prim) -> bool:
    from pxr import UsdPhysics

    return prim.IsA(UsdPhysics.Joint) and UsdPhysics.Joint(prim).GetJointEnabledAttr().Get() is False


def _without_disabled_joints(stage, file: Path, folder: Path) -> str:
    """The file MuJoCo's importer should read: ``file`` itself, or, when joints have
    ``physics:jointEnabled = false`` (which the importer does not read), a layer over it that
    deactivates them. As in PhysX, a disabled joint does not connect its bodies: a body it
    held becomes a free body, carrying the links jointed below it."""
    from pxr import Sdf

    disabled = [prim.GetPath() for prim in stage.Traverse() if _disabled(prim)]
    if not disabled:
        return str(file)
    source = stage.GetRootLayer()
    layer = Sdf.Layer.CreateAnonymous(".usda")
    for key in source.pseudoRoot.ListInfoKeys():  # defaultPrim, upAxis, metersPerUnit: not inherited
        if key not in ("subLayers", "subLayerOffsets"):
            layer.pseudoRoot.SetInfo(key, source.pseudoRoot.GetInfo(key))
    layer.subLayerPaths.append(str(file.resolve()))
    for path in disabled:
        Sdf.CreatePrimInLayer(layer, path).active = False
    over = folder / f"{file.stem}.joints_enabled.usda"
    layer.Export(str(over))
    return str(over)


def _pxr_problem(message: str, file: Path) -> str:
    """pxr's first ``file:line:col: problem`` (a syntax error's place), else its last error.

    pxr's exception holds one "Error in '<function>' at line N in file <pxr source> : '<what>'"
    per error; the first says where the stage is broken, the last only "Failed to open layer"."""
    problems = re.findall(r"Error in '[^']*' at line \d+ in file [^:]* : '(.*?)'\s*(?=\n\s*Error in|$)",
                          message.strip(), flags=re.S)
    problems = [" ".join(p.split()) for p in problems] or [message.strip().splitlines()[-1].strip()]
    for problem in problems:
        if located := re.match(r"(\S+:\d+:\d+): (.*)", problem):
            return f"{located.group(1)}: not a readable USD stage: {located.group(2)}"
    return f"{file}: not a readable USD stage ({problems[-1]})"


def _default_prim_path(stage, file: Path) -> str:
    """The path that element names are made relative to (see the module docstring)."""
    roots = [str(p.GetPath()) for p in stage.GetPseudoRoot().GetChildren()]
    named = stage.GetRootLayer().defaultPrim
    if named:
        default = stage.GetDefaultPrim()
        if not default:
            raise AssetError(
                f"{file}: defaultPrim {named!r} names no prim (root prims: {', '.join(roots) or 'none'}); "
                "set defaultPrim to the robot's root prim.")
        return str(default.GetPath())
    if len(roots) == 1:
        warnings.warn(
            f"{file.name}: the stage has no defaultPrim; using its only root prim {roots[0]} (set "
            f"defaultPrim = \"{roots[0][1:]}\" in the layer metadata to silence this).", stacklevel=4)
        return roots[0]
    raise AssetError(
        f"{file}: the stage has no defaultPrim and {len(roots)} root prims ({', '.join(roots)}); "
        "set defaultPrim to the robot's root prim (stage.SetDefaultPrim).")


def _check_limits(stage, file: Path) -> None:
    from pxr import UsdPhysics

    for prim in stage.Traverse():
        for cls in (UsdPhysics.RevoluteJoint, UsdPhysics.PrismaticJoint):
            if not prim.IsA(cls):
                continue
            joint = cls(prim)
            lower, upper = joint.GetLowerLimitAttr().Get(), joint.GetUpperLimitAttr().Get()
            if lower is not None and upper is not None and math.isfinite(lower) and lower > upper:
                raise AssetError(
                    f"{file}: joint {prim.GetPath()}: lower limit {lower:g} > upper limit {upper:g}; "
                    "swap physics:lowerLimit and physics:upperLimit.")


def _drop_reason(prim, stage) -> str | None:
    """Why MuJoCo's USD importer dropped joint ``prim``; None for a fixed joint (welded)."""
    from pxr import UsdPhysics

    if prim.IsA(UsdPhysics.FixedJoint) or _disabled(prim):
        return None  # welded, or left out on purpose (jointEnabled = false)
    if not (prim.IsA(UsdPhysics.RevoluteJoint) or prim.IsA(UsdPhysics.PrismaticJoint)):
        kind = str(prim.GetTypeName()).removeprefix("Physics")
        return f"{'generic (D6) Joint' if kind in ('Joint', '') else kind} joints are not supported"
    joint = UsdPhysics.Joint(prim)
    if joint.GetExcludeFromArticulationAttr().Get():
        return "excluded from the articulation (a loop closure); its body1 moves freely"

    def rigid(targets) -> bool:
        return bool(targets) and stage.GetPrimAtPath(targets[0]).HasAPI(UsdPhysics.RigidBodyAPI)

    body0, body1 = joint.GetBody0Rel().GetTargets(), joint.GetBody1Rel().GetTargets()
    if not rigid(body1):
        return f"body1 {[str(b) for b in body1]} is not a rigid body; its child moves freely"
    if body0 and not rigid(body0):
        return (f"body0 {[str(b) for b in body0]} is not a rigid body; leave body0 empty to attach "
                "a link to the world")
    return "MuJoCo's importer skipped it"


def _warn_dropped_joints(stage, spec: mujoco.MjSpec, relative, file: Path) -> None:
    from pxr import UsdPhysics

    dropped = []
    for prim in stage.Traverse():
        if prim.IsA(UsdPhysics.Joint) and spec.joint(relative(str(prim.GetPath()))) is None:
            reason = _drop_reason(prim, stage)
            if reason:
                dropped.append(f"{prim.GetPath()} ({reason})")
    if dropped:
        warnings.warn(f"{file.name}: MuJoCo's USD importer dropped {len(dropped)} joints: "
                      f"{'; '.join(dropped)}", stacklevel=4)


def _add_drives(stage, spec: mujoco.MjSpec, relative) -> None:
    """Turn UsdPhysics DriveAPI gains into ambulo drives (MuJoCo's importer skips them)."""
    from pxr import UsdPhysics

    for prim in stage.Traverse():
        if not prim.IsA(UsdPhysics.Joint):
            continue
        joint = spec.joint(relative(str(prim.GetPath())))
        if joint is None:
            continue
        for kind in ("angular", "linear"):
            drive = UsdPhysics.DriveAPI.Get(prim, kind)
            if not drive or not prim.HasAPI(UsdPhysics.DriveAPI, kind):
                continue
            scale = _PER_RAD if kind == "angular" else 1.0
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
