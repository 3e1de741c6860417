"""Stage helpers: referencing robot/scene files at a prim path, as Isaac's ``add_reference_to_stage``."""

from __future__ import annotations

import os

import mujoco

from .drives import DriveDefaults
from .importers import load_spec


_OPTION_FIELDS = [f for f in dir(mujoco.MjSpec().option) if not f.startswith("_")]


def get_current_stage() -> mujoco.MjSpec:
    """The stage of the current World."""
    from .world import World  # noqa: PLC0415

    world = World.instance()
    if world is None:
        raise RuntimeError("no World exists yet: create one with World() first")
    return world.stage


def add_reference_to_stage(
    usd_path: str | os.PathLike,
    prim_path: str,
    *,
    drive_stiffness: float = 100.0,
    drive_damping: float = 5.0,
    fixed_base: bool = False,
) -> mujoco.MjsFrame:
    """Place the file ``usd_path`` (USD, URDF or MJCF, despite the name) at ``prim_path``.

    The file's default prim (MJCF/URDF: its world body; USD: the stage's
    defaultPrim) becomes ``prim_path``, so a child ``box`` lands at
    ``prim_path/box``. Joints without a drive get one with ``drive_stiffness``
    (N*m/rad) and ``drive_damping`` (N*m*s/rad). ``fixed_base`` welds the root body to the
    world (Isaac's "fix base"): a robot on a gantry, an arm on a table.

    Returns the frame that holds the reference (its pose is the prim's pose).
    """
    if not str(prim_path).startswith("/"):
        raise ValueError(f"prim_path must be absolute, like '/World/Robot'; got {prim_path!r}")
    stage = get_current_stage()
    prim_path = prim_path.rstrip("/")
    if stage.frame(prim_path) is not None or stage.body(prim_path) is not None:
        raise ValueError(f"{prim_path!r} is already on the stage; reference at another prim path")
    spec = load_spec(usd_path, drives=DriveDefaults(stiffness=drive_stiffness, damping=drive_damping),
                     fixed_base=fixed_base)
    # keyframes of one robot do not fit a stage with others: the initial state is
    # the model's qpos0 plus whatever objects set before reset
    for key in list(spec.keys):
        spec.delete(key)
    # the World's physics settings win; copying them avoids attach-conflict noise
    for field in _OPTION_FIELDS:
        setattr(spec.option, field, getattr(stage.option, field))
    frame = stage.worldbody.add_frame(name=prim_path)
    stage.attach(spec, prefix=prim_path + "/", frame=frame)
    return frame
