"""What Kit's USD commands share: the stage they act on, the prims made through the ambulo API,
and writing a prim's local transform into its xform ops.

Prims made through the ambulo API (a referenced or imported robot, ``scene.add`` objects) are
placeholders on the USD stage (``ambulo.sim.usd_stage``); their physics is in the MuJoCo model.
A referenced robot's placeholder is moved with its frame in the model (``model_frame``);
other edits of placeholders fail in one line (``api_made_error``).
"""

from __future__ import annotations

from ambulo.sim.current import current_world_or_none

from .stage_utils import synced_usd_stage

ROOT = "/World"


def _pxr():
    from pxr import Gf, Sdf, Usd, UsdGeom

    return Gf, Sdf, Usd, UsdGeom


def command_stage(stage_or_context=None):
    """The stage a command acts on: the one given (a stage or a UsdContext), else the World's."""
    if stage_or_context is not None and hasattr(stage_or_context, "GetPrimAtPath"):
        return stage_or_context
    if stage_or_context is not None and hasattr(stage_or_context, "get_stage"):
        return stage_or_context.get_stage()
    return synced_usd_stage().stage


def plain(value):
    """numpy arrays and scalars as the Python values pxr converts."""
    return value.tolist() if hasattr(value, "tolist") else value


def api_made_error(path: str, what: str) -> ValueError:
    return ValueError(f"{what}: {path} was made through the ambulo API (a referenced robot or a scene object), its "
                      "physics is in the MuJoCo model; do it through the Isaac API (set_world_pose, Articulation "
                      "gains, world.scene.remove_object) or author the prim with pxr")


def authored_prim(stage, path: str, what: str):
    """The authored prim at ``path``: an error if it does not exist or was made through the API."""
    prim = stage.GetPrimAtPath(str(path))
    if not prim.IsValid():
        raise ValueError(f"{what}: no prim at {str(path)!r}; check the path")
    if synced_usd_stage().is_mirrored(str(path)):
        raise api_made_error(str(path), what)
    return prim


def default_xform_ops(prim) -> None:
    """Isaac's default ops for new prims ("Scale, Orient, Translate", double precision)."""
    Gf, Sdf, _, UsdGeom = _pxr()
    if not prim.IsA(UsdGeom.Xformable) or UsdGeom.Xformable(prim).GetOrderedXformOps():
        return
    for name, kind, value in (("xformOp:translate", Sdf.ValueTypeNames.Double3, Gf.Vec3d(0.0)),
                              ("xformOp:orient", Sdf.ValueTypeNames.Quatd, Gf.Quatd(1.0)),
                              ("xformOp:scale", Sdf.ValueTypeNames.Double3, Gf.Vec3d(1.0))):
        prim.CreateAttribute(name, kind, False).Set(value)
    prim.CreateAttribute("xformOpOrder", Sdf.ValueTypeNames.TokenArray, False).Set(
        ["xformOp:translate", "xformOp:orient", "xformOp:scale"])


def is_inside(path: str, root: str) -> bool:
    return path == root or path.startswith(root.rstrip("/") + "/")


def set_local_matrix(prim, matrix) -> None:
    """Write ``matrix`` (``Gf.Matrix4d``) as the prim's local transform, into its translate,
    orient/rotateXYZ and scale ops (made as Isaac's defaults if it has other ops or none)."""
    Gf, _, _, UsdGeom = _pxr()
    transform = Gf.Transform(matrix)
    write_srt(prim, transform.GetTranslation(), transform.GetRotation(), transform.GetScale())


def write_srt(prim, translation=None, rotation=None, scale=None) -> None:
    """Set the given parts of the prim's local transform (``rotation`` a ``Gf.Rotation``), in its own ops."""
    Gf, _, _, UsdGeom = _pxr()
    frame = model_frame(prim)  # before writing: a placeholder that cannot move fails untouched
    xform = UsdGeom.Xformable(prim)
    T = UsdGeom.XformOp
    ops = {op.GetOpType(): op for op in xform.GetOrderedXformOps()}
    if not set(ops) <= {T.TypeTranslate, T.TypeOrient, T.TypeRotateXYZ, T.TypeScale} \
            or len(ops) != len(xform.GetOrderedXformOps()):
        keep = Gf.Transform(xform.GetLocalTransformation())
        translation = keep.GetTranslation() if translation is None else translation
        rotation = keep.GetRotation() if rotation is None else rotation
        scale = keep.GetScale() if scale is None else scale
        xform.ClearXformOpOrder()
        ops = {}
    if not ops:
        default_xform_ops(prim)
        ops = {op.GetOpType(): op for op in xform.GetOrderedXformOps()}
    double = T.PrecisionDouble
    if translation is not None:
        op = ops.get(T.TypeTranslate) or xform.AddTranslateOp(double)
        op.Set((Gf.Vec3d if op.GetPrecision() == double else Gf.Vec3f)(*map(float, translation)))
    if rotation is not None:
        if T.TypeRotateXYZ in ops:
            z, y, x = rotation.Decompose(Gf.Vec3d.ZAxis(), Gf.Vec3d.YAxis(), Gf.Vec3d.XAxis())
            op = ops[T.TypeRotateXYZ]
            op.Set((Gf.Vec3d if op.GetPrecision() == double else Gf.Vec3f)(x, y, z))
        else:
            op = ops.get(T.TypeOrient) or xform.AddOrientOp(double)
            quat = rotation.GetQuat()
            op.Set(Gf.Quatd(quat) if op.GetPrecision() == double else Gf.Quatf(quat))
    if scale is not None:
        op = ops.get(T.TypeScale) or xform.AddScaleOp(double)
        op.Set((Gf.Vec3d if op.GetPrecision() == double else Gf.Vec3f)(*map(float, scale)))
    if frame is not None:
        place_model_frame(frame, prim, current_world_or_none().stage_units_in_meters)


def model_frame(prim):
    """The MuJoCo frame a referenced robot's placeholder prim moves, None for an authored prim (or a
    robot whose World does not exist yet: ``place_model_frame`` places it when the World adopts
    it); an error for other API-made prims."""
    path, world = str(prim.GetPath()), current_world_or_none()
    if world is None or not synced_usd_stage().is_mirrored(path):
        return None
    frame = world.sim.spec.frame(path) if str(prim.GetParent().GetPath()) in (ROOT, "/") else None
    if frame is None:
        raise api_made_error(path, "transforming it")
    return frame


def place_model_frame(frame, prim, meters_per_unit: float) -> None:
    """``frame`` (an ``MjsFrame`` under the world) at the prim's local pose, in metres."""
    Gf, _, _, UsdGeom = _pxr()
    transform = Gf.Transform(UsdGeom.Xformable(prim).GetLocalTransformation())
    quat = transform.GetRotation().GetQuat()
    frame.pos = [float(c) * meters_per_unit for c in transform.GetTranslation()]
    frame.quat = [quat.GetReal(), *map(float, quat.GetImaginary())]


__all__ = ["ROOT", "api_made_error", "authored_prim", "command_stage", "default_xform_ops", "is_inside",
           "model_frame", "place_model_frame", "plain", "set_local_matrix", "write_srt"]
