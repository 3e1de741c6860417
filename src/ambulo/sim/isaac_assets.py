"""Isaac Sim asset paths (``get_assets_root_path() + "/Isaac/Robots/..."``) mapped to files ambulo has.

Isaac scripts name assets on NVIDIA's Nucleus server or S3 bucket. ambulo cannot download
them (and their USD needs Omniverse's materials), so each path a tutorial uses maps to a
bundled model or a robot shipped by a pip package (``example-robot-data``). The lookup keys
on the part after ``/Isaac/`` and is case-insensitive, so the bundled root, an
``omniverse://`` URL and an ``https://`` URL all resolve the same way.

The Isaac-style entry points resolve these paths (``resolve_asset``) before the core's
``add_robot``, which knows only paths and bundled names (``ambulo.core.scene.resolve_file``).
"""

from __future__ import annotations

import os
import re

from ..assets import path as bundled
from ..core.importers.packages import resolve_package_uri
from ..core.scene import resolve_file

_BUNDLED = {
    "robots/jetbot/jetbot.usd": "jetbot",
    "robots/nvidia/jetbot/jetbot.usd": "jetbot",
    "robots/humanoid/humanoid.usd": "humanoid",
    "robots/humanoid/humanoid_instanceable.usd": "humanoid",
    "environments/simple_warehouse/warehouse.usd": "simple_warehouse",
    "environments/simple_warehouse/full_warehouse.usd": "simple_warehouse",
    "environments/simple_warehouse/warehouse_with_forklifts.usd": "simple_warehouse",
    "environments/grid/default_environment.usd": "grid_environment",
    "environments/grid/gridroom_curved.usd": "grid_environment",
}
"""Isaac path (after ``/Isaac/``, lower case) -> bundled asset name."""

_PACKAGED = {
    "robots/franka/franka.usd": "package://example-robot-data/robots/panda_description/urdf/panda.urdf",
    "robots/franka/franka_alt_fingers.usd": "package://example-robot-data/robots/panda_description/urdf/panda.urdf",
    "robots/frankarobotics/frankapanda/franka.usd":
        "package://example-robot-data/robots/panda_description/urdf/panda.urdf",
    "robots/unitree/g1/g1.usd": "package://example-robot-data/robots/g1_description/urdf/g1_29dof_rev_1_0.urdf",
    "robots/unitree/go2/go2.usd": "package://example-robot-data/robots/go2_description/urdf/go2.urdf",
    "robots/unitree/go1/go1.usd": "package://example-robot-data/robots/go1_description/urdf/go1.urdf",
    "robots/ur10/ur10.usd": "package://example-robot-data/robots/ur_description/urdf/ur10_robot.urdf",
    "robots/universalrobots/ur10/ur10.usd": "package://example-robot-data/robots/ur_description/urdf/ur10_robot.urdf",
    "robots/universalrobots/ur5/ur5.usd": "package://example-robot-data/robots/ur_description/urdf/ur5_robot.urdf",
}
"""Isaac path -> a robot file shipped by ``example-robot-data`` (the ``robots`` extra)."""

_ISAAC_PART = re.compile(r"(?:^|.*/)(Isaac/(.+))$", re.IGNORECASE)
"""The path after the last ``/Isaac/`` (S3 URLs hold two: ``.../Assets/Isaac/4.5/Isaac/Robots/...``)."""


def is_isaac_path(file: str) -> bool:
    """Whether ``file`` names an asset of Isaac's library (``.../Isaac/Robots/...``)."""
    return bool(_ISAAC_PART.search(str(file).replace("\\", "/"))) and not _exists(file)


def resolve_isaac_path(file: str) -> str:
    """The local file standing in for Isaac asset ``file``; FileNotFoundError naming what exists."""
    match = _ISAAC_PART.search(str(file).replace("\\", "/"))
    key = match.group(2).lower() if match else ""
    if key in _BUNDLED:
        return bundled(_BUNDLED[key])
    if key in _PACKAGED:
        try:
            return resolve_package_uri(_PACKAGED[key])
        except FileNotFoundError:
            raise FileNotFoundError(
                f"the Isaac asset {match.group(1)} maps to {_PACKAGED[key]}, which is not "
                "installed; pip install 'ambulo[robots]'") from None
    folders = sorted({k.split("/")[1] for k in (*_BUNDLED, *_PACKAGED)})
    raise FileNotFoundError(
        f"ambulo has no stand-in for the Isaac asset {match.group(1) if match else file}; it has stand-ins "
        f"under Isaac/Robots and Isaac/Environments for {', '.join(folders)} (or reference a URDF, MJCF or "
        "USD file of your own)")


def _exists(file: str) -> bool:
    return os.path.exists(file)


def resolve_asset(file: str | os.PathLike) -> str:
    """``file`` as the file to load: an Isaac library path (``<root>/Isaac/Robots/...``) as the file
    standing in for it, else as ``ambulo.core.scene.resolve_file`` says (a path as given if it
    exists, a bare name as the bundled asset of that name)."""
    text = str(file)
    if is_isaac_path(text):
        return resolve_isaac_path(text)
    return resolve_file(text)


__all__ = ["is_isaac_path", "resolve_asset", "resolve_isaac_path"]
