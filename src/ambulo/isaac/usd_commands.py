"""Kit's USD commands (``omni.usd.commands``, ``omni.kit.primitive.mesh``) on the World's USD stage.

Each authors what Kit's command authors: ``CreatePrim`` defines the prim with Isaac's default
xform ops (translate, orient, scale in double precision), ``ChangeProperty`` sets one
attribute, ``DeletePrims`` removes prims, ... Authored prims are simulated from the next
``world.reset()`` (``ambulo.sim.usd_stage``), so a deleted body leaves the simulation and a
changed attribute changes it then.

Prims made through the ambulo API (a referenced or imported robot, ``scene.add`` objects) are
placeholders on the stage, their physics in the MuJoCo model: ``DeletePrims`` removes them
from the model too, and ``TransformPrim``/``TransformPrimSRT`` move a referenced robot's frame.
Other commands on them (rename, copy, deactivate, change an attribute they lack) fail in one
line saying how to do it through the Isaac API.
"""

from __future__ import annotations

import warnings

from ambulo.sim.current import current_world_or_none

from .kit_commands import Command
from .mesh_prims import define_mesh
from .omni_usd import get_stage_next_free_path
from .stage_utils import add_reference_to_stage, synced_usd_stage
from .usd_edit import (
    ROOT,
    api_made_error,
    authored_prim,
    command_stage,
    default_xform_ops,
    is_inside,
    plain,
    set_local_matrix,
    write_srt,
)


def _pxr():
    from pxr import Gf, Sdf, Usd, UsdGeom

    return Gf, Sdf, Usd, UsdGeom


# -- creating prims ---------------------------------------------------------------
class CreatePrimWithDefaultXformCommand(Command):
    """Define a prim of ``prim_type`` at ``prim_path`` (default: ``/World/<prim_type>``, made unique)."""

    def __init__(self, prim_type: str, prim_path: str | None = None, select_new_prim: bool = True,
                 attributes: dict | None = None, create_default_xform: bool = True, stage=None,
                 context_name: str | None = None):
        self._type, self._path, self._attributes = prim_type, prim_path, dict(attributes or {})
        self._default_xform, self._stage = create_default_xform, command_stage(stage)

    def do(self):
        _, _, Usd, UsdGeom = _pxr()
        stage = self._stage
        path = str(self._path or get_stage_next_free_path(stage, "/" + self._type, True))
        prim = stage.DefinePrim(path, self._type)
        for name, value in self._attributes.items():
            attr = prim.GetAttribute(name)
            if not attr:
                raise ValueError(f"CreatePrim: a {self._type} has no attribute {name!r}; see its UsdGeom schema")
            attr.Set(plain(value))
        self._path = path
        if prim.IsA(UsdGeom.Cylinder) or prim.IsA(UsdGeom.Capsule) or prim.IsA(UsdGeom.Cone):
            prim.GetAttribute("axis").Set(UsdGeom.GetStageUpAxis(stage))
        if self._default_xform:
            default_xform_ops(prim)
        extent = prim.GetAttribute("extent")
        if extent and "extent" not in self._attributes:
            bounds = UsdGeom.Boundable.ComputeExtentFromPlugins(UsdGeom.Boundable(prim), Usd.TimeCode.Default())
            if bounds is not None:
                extent.Set(bounds)

    def undo(self):
        self._stage.RemovePrim(self._path)


class CreatePrimCommand(CreatePrimWithDefaultXformCommand):
    """The same as ``CreatePrimWithDefaultXform`` (Kit keeps both names)."""


class CreateMeshPrimWithDefaultXformCommand(Command):
    """A ``UsdGeom.Mesh`` Cube/Sphere/Cylinder/Cone/Torus/Plane/Disk of half size ``half_scale`` cm
    (default 50: a 1 m cube) at ``prim_path`` (default ``/World/<Type>``); returns its path."""

    def __init__(self, prim_type: str, **kwargs):
        self._type = prim_type[:1].upper() + prim_type[1:].lower()
        self._kwargs = kwargs
        self._stage = command_stage(kwargs.get("stage"))
        self._path = None

    def do(self) -> str:
        _, _, _, UsdGeom = _pxr()
        kw = self._kwargs
        path = get_stage_next_free_path(self._stage, kw.get("prim_path") or "/" + self._type,
                                        kw.get("prepend_default_prim", True))
        origin = kw.get("object_origin")
        if origin is None and kw.get("above_ground") and self._type not in ("Plane", "Disk"):
            half = (kw.get("half_scale") or 50.0) * 0.01 / UsdGeom.GetStageMetersPerUnit(self._stage)
            origin = (0.0, 0.0, half / 2.0 if self._type == "Torus" else half)
        define_mesh(self._stage, path, self._type, kw.get("half_scale"), origin)
        self._path = path
        return path

    def undo(self):
        if self._path:
            self._stage.RemovePrim(self._path)


class CreateMeshPrimCommand(CreateMeshPrimWithDefaultXformCommand):
    """The same as ``CreateMeshPrimWithDefaultXform`` (Kit keeps both names)."""


class CreateReferenceCommand(Command):
    """Reference ``asset_path`` (USD, URDF, MJCF or an Isaac library path) at ``path_to``; returns the prim."""

    def __init__(self, usd_context=None, path_to=None, asset_path: str | None = None, prim_path=None,
                 instanceable: bool = True, select_prim: bool = True):
        if path_to is None or asset_path is None:
            raise TypeError(f"{type(self).__name__} needs path_to= and asset_path=")
        self._path, self._asset = str(path_to), str(asset_path)

    def do(self):
        return add_reference_to_stage(self._asset, self._path)


class CreatePayloadCommand(CreateReferenceCommand):
    """As ``CreateReference``: ambulo loads a payload at once, as Kit does by default."""


class AddReferenceCommand(Command):
    """Add ``reference`` (an ``Sdf.Reference``) to the prim at ``prim_path``."""

    def __init__(self, stage=None, prim_path=None, reference=None, position=None):
        self._path, self._asset = str(prim_path), str(getattr(reference, "assetPath", reference))

    def do(self):
        add_reference_to_stage(self._asset, self._path)


# -- deleting, copying, moving -------------------------------------------------------
def _remove_from_model(path: str) -> None:
    """Remove what the ambulo API made at ``path`` (bodies, frames, lights, scene objects) from the World."""
    world = current_world_or_none()
    if world is None:
        return
    spec = world.sim.spec
    bodies = [b for b in spec.bodies if b.name and is_inside(b.name, path)]
    names = {b.name for b in bodies}
    for body in [b for b in bodies if b.parent.name not in names]:  # a body's subtree goes with it
        spec.delete(body)
    for element in [e for group in (spec.frames, spec.lights) for e in group if e.name and is_inside(e.name, path)]:
        spec.delete(element)
    for obj in list(world.scene.objects()):
        if is_inside(str(getattr(obj, "prim_path", "")), path):
            world.scene.remove_object(obj.name)


class DeletePrimsCommand(Command):
    """Delete the prims at ``paths`` and what is under them; a path with no prim is skipped with a
    warning, as Kit logs it. Deleted bodies leave the simulation at the next ``world.reset()``."""

    def __init__(self, paths, destructive: bool = True, stage=None, context_name: str | None = None):
        self._paths = [str(p) for p in ([paths] if isinstance(paths, str) else paths)]
        self._stage = command_stage(stage)
        self._saved = None

    def do(self):
        _, Sdf, _, _ = _pxr()
        stage, usd = self._stage, synced_usd_stage()
        missing = [p for p in self._paths if not stage.GetPrimAtPath(p).IsValid()]
        if missing:
            warnings.warn(f"DeletePrims: no prim at {', '.join(missing)}; skipped", stacklevel=3)
        paths = [p for p in self._paths if p not in missing]
        if ROOT in paths or "/" in paths:
            raise ValueError(f"DeletePrims: {ROOT} is the root of ambulo's stage; delete the prims under it")
        layer, self._saved = stage.GetRootLayer(), Sdf.Layer.CreateAnonymous()
        self._undoable = []
        for path in paths:
            if not usd.is_mirrored(path) and layer.GetPrimAtPath(path):  # authored: kept for undo
                Sdf.CreatePrimInLayer(self._saved, path)
                Sdf.CopySpec(layer, path, self._saved, path)
                self._undoable.append(path)
            _remove_from_model(path)  # what the API made there, and scene objects wrapping the prim
            stage.RemovePrim(path)

    def undo(self):
        _, Sdf, _, _ = _pxr()
        for path in self._undoable:
            Sdf.CreatePrimInLayer(self._stage.GetRootLayer(), path)
            Sdf.CopySpec(self._saved, path, self._stage.GetRootLayer(), path)


class CopyPrimCommand(Command):
    """Copy the authored prim ``path_from`` (and its subtree) to ``path_to`` (made unique)."""

    def __init__(self, path_from: str, path_to: str | None = None, duplicate_layers: bool = False,
                 combine_layers: bool = False, exclusive_select: bool = True, usd_context_name: str = "",
                 flatten_references: bool = False, copy_to_introducing_layer: bool = False):
        self._stage = command_stage()
        self._from = str(path_from)
        self._to = get_stage_next_free_path(self._stage, str(path_to or path_from), False)

    def do(self):
        _, Sdf, _, _ = _pxr()
        authored_prim(self._stage, self._from, "CopyPrim")
        layer = self._stage.GetRootLayer()
        Sdf.CreatePrimInLayer(layer, self._to)
        Sdf.CopySpec(layer, self._from, layer, self._to)

    def undo(self):
        self._stage.RemovePrim(self._to)

    def modify_callback_info(self, cb_type, cmd_args):
        return {**cmd_args, "path_to": self._to}


class CopyPrimsCommand(Command):
    def __init__(self, paths_from, paths_to=None, duplicate_layers: bool = False, combine_layers: bool = False,
                 flatten_references: bool = False, copy_to_introducing_layer: bool = False):
        targets = list(paths_to or [])
        self._copies = [CopyPrimCommand(p, targets[i] if i < len(targets) else None) for i, p in enumerate(paths_from)]

    def do(self):
        for copy in self._copies:
            copy.do()

    def undo(self):
        for copy in reversed(self._copies):
            copy.undo()


def _retarget(stage, old: str, new: str) -> None:
    """Relationships (joint bodies, material bindings) that pointed into ``old`` now point into ``new``."""
    _, Sdf, _, _ = _pxr()
    for prim in stage.Traverse():
        for rel in prim.GetRelationships():
            targets = rel.GetTargets()
            moved = [Sdf.Path(new + str(t)[len(old):]) if is_inside(str(t), old) else t for t in targets]
            if moved != list(targets):
                rel.SetTargets(moved)


class MovePrimCommand(Command):
    """Move (rename or re-parent) the authored prim ``path_from`` to ``path_to``, keeping its world
    transform when its parent changes (``keep_world_transform``), and retarget relationships to it."""

    def __init__(self, path_from, path_to, time_code=None, keep_world_transform: bool = True, on_move_fn=None,
                 destructive: bool = True, stage_or_context=None, resolve_reference: bool = True):
        self._stage, self._from, self._to = command_stage(stage_or_context), str(path_from), str(path_to)
        self._keep, self._on_move = keep_world_transform, on_move_fn

    def _move(self, src: str, dst: str) -> None:
        _, Sdf, Usd, UsdGeom = _pxr()
        stage = self._stage
        prim = authored_prim(stage, src, "MovePrim")
        if stage.GetPrimAtPath(dst).IsValid():
            raise ValueError(f"MovePrim: a prim already exists at {dst!r}; delete it or pick another path")
        world = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default()) \
            if prim.IsA(UsdGeom.Xformable) else None
        layer = stage.GetRootLayer()
        Sdf.CreatePrimInLayer(layer, dst)
        Sdf.CopySpec(layer, src, layer, dst)
        stage.RemovePrim(src)
        _retarget(stage, src, dst)
        moved = stage.GetPrimAtPath(dst)
        if self._keep and world is not None and Sdf.Path(src).GetParentPath() != Sdf.Path(dst).GetParentPath():
            parent = UsdGeom.Xformable(moved.GetParent())
            parent_world = parent.ComputeLocalToWorldTransform(Usd.TimeCode.Default()) if parent else None
            set_local_matrix(moved, world * parent_world.GetInverse() if parent_world is not None else world)
        if self._on_move is not None:
            self._on_move(src, dst)

    def do(self):
        self._move(self._from, self._to)

    def undo(self):
        self._move(self._to, self._from)


class MovePrimsCommand(Command):
    def __init__(self, paths_to_move: dict, time_code=None, keep_world_transform: bool = True, on_move_fn=None,
                 destructive: bool = True, stage_or_context=None):
        self._moves = [MovePrimCommand(src, dst, keep_world_transform=keep_world_transform, on_move_fn=on_move_fn,
                                       stage_or_context=stage_or_context) for src, dst in paths_to_move.items()]

    def do(self):
        for move in self._moves:
            move.do()

    def undo(self):
        for move in reversed(self._moves):
            move.undo()


class ToggleActivePrimsCommand(Command):
    """Deactivate (or activate) authored prims: an inactive prim and its subtree are not simulated."""

    def __init__(self, prim_paths, stage_or_context=None, active: bool | None = None):
        self._stage, self._paths, self._active = command_stage(stage_or_context), [str(p) for p in prim_paths], active
        self._before: dict[str, bool] = {}

    def do(self):
        for path in self._paths:
            prim = authored_prim(self._stage, path, "ToggleActivePrims")
            self._before[path] = prim.IsActive()
            prim.SetActive(not prim.IsActive() if self._active is None else bool(self._active))

    def undo(self):
        for path, active in self._before.items():
            self._stage.GetPrimAtPath(path).SetActive(active)


# -- properties and transforms -----------------------------------------------------------
class ChangePropertyCommand(Command):
    """Set the attribute (or relationship targets) at ``prop_path`` (``/World/Cube.size``) to ``value``,
    creating it with ``type_to_create_if_not_exist`` when missing."""

    def __init__(self, prop_path, value, prev=None, timecode=None, type_to_create_if_not_exist=None,
                 target_layer=None, usd_context_name="", is_custom: bool = False, variability=None):
        self._path, self._value, self._prev, self._time = str(prop_path), plain(value), prev, timecode
        self._type, self._custom, self._variability = type_to_create_if_not_exist, is_custom, variability
        self._stage = command_stage(usd_context_name or None)

    def _set(self, value) -> None:
        _, Sdf, Usd, _ = _pxr()
        prop = self._stage.GetPropertyAtPath(self._path)
        if not prop:
            prim_path, _, name = self._path.partition(".")
            prim = self._stage.GetPrimAtPath(prim_path)
            if not prim.IsValid():
                raise ValueError(f"ChangeProperty: no prim at {prim_path!r} (from {self._path!r}); check the path")
            if self._type is None:
                if synced_usd_stage().is_mirrored(prim_path):
                    raise api_made_error(prim_path, f"ChangeProperty {name!r}")
                raise ValueError(f"ChangeProperty: {prim_path} has no property {name!r}; check the name or pass "
                                 "type_to_create_if_not_exist=Sdf.ValueTypeNames.<type>")
            prop = prim.CreateAttribute(name, self._type, self._custom,
                                        self._variability if self._variability is not None else Sdf.VariabilityVarying)
        if isinstance(prop, Usd.Relationship):
            prop.SetTargets([Sdf.Path(str(t)) for t in (value if isinstance(value, (list, tuple)) else [value])])
        else:
            prop.Set(value, self._time if self._time is not None else Usd.TimeCode.Default())

    def do(self):
        prop = self._stage.GetPropertyAtPath(self._path)
        if self._prev is None and prop and hasattr(prop, "Get"):
            self._prev = prop.Get()
        self._set(self._value)

    def undo(self):
        if self._prev is not None:
            self._set(self._prev)


class TransformPrimCommand(Command):
    """Set the prim's local transform to ``new_transform_matrix`` (``Gf.Matrix4d``)."""

    def __init__(self, path, new_transform_matrix, old_transform_matrix=None, time_code=None,
                 had_transform_at_key: bool = False, usd_context_name: str = ""):
        self._stage, self._path = command_stage(usd_context_name or None), str(path)
        self._new, self._old = new_transform_matrix, old_transform_matrix

    def do(self):
        _, _, _, UsdGeom = _pxr()
        prim = self._stage.GetPrimAtPath(self._path)
        if not prim.IsValid():
            raise ValueError(f"TransformPrim: no prim at {self._path!r}; check the path")
        if self._old is None:
            self._old = UsdGeom.Xformable(prim).GetLocalTransformation()
        set_local_matrix(prim, self._new)

    def undo(self):
        set_local_matrix(self._stage.GetPrimAtPath(self._path), self._old)


class TransformPrimSRTCommand(Command):
    """Set the prim's local translation, rotation (Euler degrees applied in ``new_rotation_order``,
    axis indices, default XYZ) and scale; parts left None keep their value."""

    def __init__(self, path, new_translation=None, new_rotation_euler=None, new_scale=None, new_rotation_order=None,
                 old_translation=None, old_rotation_euler=None, old_rotation_order=None, old_scale=None,
                 time_code=None, had_transform_at_key: bool = False, usd_context_name: str = ""):
        self._stage, self._path = command_stage(usd_context_name or None), str(path)
        self._translation, self._euler, self._scale = new_translation, new_rotation_euler, new_scale
        self._order = tuple(new_rotation_order) if new_rotation_order is not None else (0, 1, 2)
        self._old = None

    def do(self):
        Gf, _, _, UsdGeom = _pxr()
        prim = self._stage.GetPrimAtPath(self._path)
        if not prim.IsValid():
            raise ValueError(f"TransformPrimSRT: no prim at {self._path!r}; check the path")
        self._old = UsdGeom.Xformable(prim).GetLocalTransformation()
        rotation = None
        if self._euler is not None:
            axes = (Gf.Vec3d.XAxis(), Gf.Vec3d.YAxis(), Gf.Vec3d.ZAxis())
            rotation = Gf.Rotation(Gf.Vec3d.XAxis(), 0.0)
            for axis in self._order:
                rotation = rotation * Gf.Rotation(axes[axis], float(self._euler[axis]))
        write_srt(prim, plain(self._translation), rotation, plain(self._scale))

    def undo(self):
        set_local_matrix(self._stage.GetPrimAtPath(self._path), self._old)


__all__: list[str] = []
