"""Isaac's ``isaacsim.core.utils.stage``: the stage is a real ``Usd.Stage`` (``ambulo.sim.usd_stage``).

``get_current_stage()`` returns the USD stage with every object the ambulo API made mirrored
on it, so ``GetPrimAtPath`` finds robots and shapes; prims a script authors with pxr are
simulated from the next ``world.reset()``.
"""

from __future__ import annotations

import os

from ambulo.sim import stage as ambulo_stage
from ambulo.sim.current import current_world_or_none
from ambulo.sim.usd_stage import current_usd_stage, new_usd_stage


def synced_usd_stage():
    """The current ``UsdStage`` with the current World's objects mirrored on it."""
    world = current_world_or_none()
    return world.synced_usd() if world is not None else current_usd_stage()


def get_current_stage(fabric: bool = False):
    """The current ``Usd.Stage``."""
    return synced_usd_stage().stage


def add_reference_to_stage(usd_path: str | os.PathLike, prim_path: str, prim_type: str = "Xform"):
    """Reference a robot or scene file (USD, URDF, MJCF, or an Isaac library path) at ``prim_path``;
    returns its ``Usd.Prim``."""
    ambulo_stage.add_reference_to_stage(usd_path=usd_path, prim_path=prim_path)
    return get_current_stage().GetPrimAtPath(prim_path)


def open_stage(usd_path: str | os.PathLike) -> bool:
    """Load a USD file as the stage; its UsdPhysics prims are simulated after the next reset."""
    current_usd_stage().open(usd_path)
    return True


def create_new_stage():
    """An empty stage; the current World goes with the old stage (make a new ``World()``)."""
    return new_usd_stage().stage


def clear_stage(predicate=None) -> None:
    """Remove every authored prim under ``/World`` (mirrored API objects stay: remove those with
    ``world.scene.remove_object``)."""
    usd = synced_usd_stage()
    for path in reversed(usd.authored_paths()):
        prim = usd.stage.GetPrimAtPath(path)
        if prim and (predicate is None or predicate(path)):
            usd.stage.RemovePrim(path)


def get_stage_units() -> float:
    """Metres per stage unit."""
    return current_usd_stage().meters_per_unit


def set_stage_units(stage_units_in_meters: float) -> None:
    from pxr import UsdGeom

    if not stage_units_in_meters > 0:
        raise ValueError(f"stage_units_in_meters must be > 0, got {stage_units_in_meters}")
    UsdGeom.SetStageMetersPerUnit(current_usd_stage().stage, float(stage_units_in_meters))


def get_stage_up_axis() -> str:
    return "Z"


def update_stage() -> None:
    """Kit applies pending USD edits here; ambulo's stage is always up to date."""


def is_stage_loading() -> bool:
    return False


def traverse_stage(fabric: bool = False):
    return get_current_stage().Traverse()


def print_stage_prim_paths(fabric: bool = False) -> None:
    for prim in traverse_stage():
        print(prim.GetPath())


__all__ = ["add_reference_to_stage", "clear_stage", "create_new_stage", "get_current_stage", "get_stage_units",
           "get_stage_up_axis", "is_stage_loading", "open_stage", "print_stage_prim_paths", "set_stage_units",
           "synced_usd_stage", "traverse_stage", "update_stage"]
