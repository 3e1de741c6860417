"""Stage helpers: referencing robot/scene files at a prim path, as Isaac's ``add_reference_to_stage``."""

from __future__ import annotations

import os

import mujoco

from ..core import DriveDefaults, RobotCfg, add_robot
from .current import current_world
from .isaac_assets import resolve_asset


def get_current_stage() -> mujoco.MjSpec:
    """The stage of the current World."""
    return current_world("using the stage").stage


def add_reference_to_stage(
    usd_path: str | os.PathLike,
    prim_path: str,
    *,
    drive_stiffness: float = 100.0,
    drive_damping: float = 5.0,
    fixed_base: bool = False,
) -> mujoco.MjsFrame:
    """Place the file ``usd_path`` (USD, URDF or MJCF, despite the name) at ``prim_path``.

    ``usd_path`` may name an asset of Isaac's library (``get_assets_root_path() +
    "/Isaac/Robots/Jetbot/jetbot.usd"``, or the Nucleus or S3 URL): the file standing in for it
    is placed (``isaac_assets``); a bare name is a bundled asset (``"jetbot"``).

    The file's default prim (MJCF/URDF: its world body; USD: the stage's
    defaultPrim) becomes ``prim_path``, so a child ``box`` lands at
    ``prim_path/box``. Joints without a drive get one with ``drive_stiffness``
    (N*m/rad) and ``drive_damping`` (N*m*s/rad). ``fixed_base`` welds the root body to the
    world (Isaac's "fix base"): a robot on a gantry, an arm on a table. The same
    ``ambulo.core.add_robot`` that RL tasks use does the work.

    Returns the frame that holds the reference (its pose is the prim's pose).
    """
    cfg = RobotCfg(file=resolve_asset(usd_path), prim_path=str(prim_path), fixed_base=fixed_base,
                   drives=DriveDefaults(stiffness=drive_stiffness, damping=drive_damping))
    return add_robot(get_current_stage(), cfg).frame
