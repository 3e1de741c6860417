"""Isaac's ``isaacsim.core.utils.prims`` on the World's USD stage."""

from __future__ import annotations

import re

from ambulo.sim.current import current_world_or_none
from ambulo.sim.prims import place_on_stage

from .stage_utils import add_reference_to_stage, get_current_stage, synced_usd_stage


def get_prim_at_path(prim_path: str, fabric: bool = False):
    """The ``Usd.Prim`` at ``prim_path`` (invalid if none: test with ``.IsValid()``)."""
    return get_current_stage().GetPrimAtPath(prim_path)


def is_prim_path_valid(prim_path: str, fabric: bool = False) -> bool:
    return bool(get_prim_at_path(prim_path).IsValid())


def get_prim_type_name(prim_path: str, fabric: bool = False) -> str:
    prim = get_prim_at_path(prim_path)
    if not prim.IsValid():
        raise ValueError(f"no prim at {prim_path!r}; check the path (is_prim_path_valid tells)")
    return str(prim.GetTypeName())


def get_prim_children(prim):
    return list(prim.GetChildren())


def get_prim_path(prim) -> str:
    return str(prim.GetPath())


def define_prim(prim_path: str, prim_type: str = "Xform", fabric: bool = False):
    """Define a new prim (Isaac raises if the path is taken; so does this)."""
    if is_prim_path_valid(prim_path):
        raise ValueError(f"a prim already exists at {prim_path!r}; pick another path or delete_prim it first")
    return get_current_stage().DefinePrim(prim_path, prim_type)


def create_prim(prim_path: str, prim_type: str = "Xform", position=None, translation=None, orientation=None,
                scale=None, usd_path: str | None = None, semantic_label: str | None = None,
                semantic_type: str = "class", attributes: dict | None = None):
    """Define a prim (or reference ``usd_path`` there) with a pose, scale and attributes.

    ``position`` is in the world frame, ``translation`` relative to the parent (the same under
    ``/World``); ``orientation`` is (w, x, y, z).
    """
    if usd_path is not None:
        prim = add_reference_to_stage(usd_path, prim_path)
        # the prims' own placement: checked, and in stage units like every other pose
        place_on_stage(prim_path, position, translation, orientation)
        return prim
    from pxr import Gf, UsdGeom

    prim = define_prim(prim_path, prim_type)
    for name, value in (attributes or {}).items():
        attr = prim.GetAttribute(name)
        if not attr:
            raise ValueError(f"{prim_type} has no attribute {name!r}; see the UsdGeom schema of {prim_type}")
        attr.Set(value)
    xform = UsdGeom.Xformable(prim)
    place = position if position is not None else translation
    if place is not None:
        xform.AddTranslateOp().Set(Gf.Vec3d(*map(float, place)))
    if orientation is not None:
        w, x, y, z = map(float, orientation)
        xform.AddOrientOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Quatd(w, x, y, z))
    if scale is not None:
        xform.AddScaleOp().Set(Gf.Vec3f(*map(float, scale)))
    if semantic_label is not None:
        from .semantics import add_update_semantics

        add_update_semantics(prim, semantic_label, semantic_type)
    return prim


def delete_prim(prim_path: str) -> None:
    """Remove the prim: an authored one from the USD stage, an ambulo object from the scene."""
    usd = synced_usd_stage()
    if not usd.stage.GetPrimAtPath(prim_path).IsValid():
        raise ValueError(f"no prim at {prim_path!r} to delete; check the path")
    if usd.is_mirrored(prim_path):
        world = current_world_or_none()
        objects = [o for o in world.scene.prims() if getattr(o, "prim_path", None) == prim_path] if world else []
        if not objects:
            raise ValueError(f"{prim_path!r} is part of an object made through the ambulo API; remove that object "
                             "with world.scene.remove_object(name)")
        world.scene.remove_object(objects[0].name)
    usd.stage.RemovePrim(prim_path)


def find_matching_prim_paths(prim_path_regex: str) -> list[str]:
    """Paths whose every component matches the regex's component (Isaac's rule for views)."""
    parts = prim_path_regex.strip("/").split("/")
    patterns = [re.compile(f"^{p}$") for p in parts]
    found = []
    for prim in get_current_stage().Traverse():
        names = str(prim.GetPath()).strip("/").split("/")
        if len(names) == len(patterns) and all(p.match(n) for p, n in zip(patterns, names)):
            found.append(str(prim.GetPath()))
    return found


__all__ = ["create_prim", "define_prim", "delete_prim", "find_matching_prim_paths", "get_prim_at_path",
           "get_prim_children", "get_prim_path", "get_prim_type_name", "is_prim_path_valid"]
