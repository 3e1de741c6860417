"""What Isaac Gym's ``AssetOptions`` change in how an asset compiles, applied to ambulo's ``MjSpec``.

- ``collapse_fixed_joints``: links joined by a fixed joint become one body, as Isaac Gym merges
  them (masses, inertias and shapes add up in the parent) - MuJoCo's ``fusestatic`` compiler pass.
  A URDF joint marked ``dont_collapse="true"`` keeps its child link a body (legged_gym's feet):
  MuJoCo never fuses a body another element references, so such links are referenced by a
  ``framepos`` sensor while the asset is probed alone, and by the sim's contact sensor (which
  names every asset body) in the batched model;
- ``replace_cylinder_with_capsule``: collision cylinders become capsules of the same radius and
  cylinder length (PhysX has no cylinder primitive; MuJoCo's cylinder contacts are slower too);
- the URDF's joint ``<limit velocity="..">`` (MuJoCo keeps no velocity limits) for the DOF
  properties' ``velocity``.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import mujoco

from .types import AssetOptions

KEEP_SENSOR = "isaacgym:keep:"
"""Name prefix of the sensors that keep a ``dont_collapse`` link a body in the probe model."""


@dataclass
class UrdfJointInfo:
    """What Isaac Gym reads from a URDF's joints that MuJoCo's model does not keep."""

    velocity: dict[str, float] = field(default_factory=dict)
    """Joint name -> ``<limit velocity>``, rad/s or m/s."""
    dont_collapse: list[str] = field(default_factory=list)
    """Child links of fixed joints marked ``dont_collapse="true"``."""
    root_link: str | None = None


def urdf_joint_info(file: str) -> UrdfJointInfo:
    """Velocity limits and ``dont_collapse`` links of a URDF (empty for other formats)."""
    info = UrdfJointInfo()
    if Path(file).suffix.lower() != ".urdf":
        return info
    robot = ET.parse(file).getroot()
    children = set()
    for joint in robot.iter("joint"):
        child = joint.find("child")
        if child is not None:
            children.add(child.get("link"))
        limit = joint.find("limit")
        if limit is not None and limit.get("velocity") and joint.get("name"):
            info.velocity[joint.get("name")] = float(limit.get("velocity"))
        if joint.get("type") == "fixed" and joint.get("dont_collapse", "").lower() == "true" and child is not None:
            info.dont_collapse.append(child.get("link"))
    roots = [link.get("name") for link in robot.iter("link") if link.get("name") not in children]
    info.root_link = roots[0] if roots else None
    return info


def apply_asset_options(spec: mujoco.MjSpec, prim_path: str, options: AssetOptions) -> None:
    """Edit the asset attached at ``prim_path`` in ``spec`` as ``options`` ask (module docstring).
    ``collapse_fixed_joints`` turns ``fusestatic`` on for the whole spec: every body of an asset
    that asks for no collapse must be referenced (the sim's contact sensor names them all)."""
    if options.collapse_fixed_joints:
        spec.compiler.fusestatic = True
    if options.replace_cylinder_with_capsule:
        prefix = prim_path.rstrip("/") + "/"
        for body in spec.bodies:
            if not (body.name or "").startswith(prefix):
                continue
            for geom in body.geoms:
                collides = geom.contype != 0 or geom.conaffinity != 0
                if collides and geom.type == mujoco.mjtGeom.mjGEOM_CYLINDER:
                    geom.type = mujoco.mjtGeom.mjGEOM_CAPSULE


def keep_links(spec: mujoco.MjSpec, prim_path: str, links: list[str]) -> None:
    """Reference ``links`` (names in the file) so that ``fusestatic`` keeps them bodies."""
    for link in links:
        name = f"{prim_path.rstrip('/')}/{link}"
        if spec.body(name) is not None:
            spec.add_sensor(name=f"{KEEP_SENSOR}{link}", type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
                            objtype=mujoco.mjtObj.mjOBJ_BODY, objname=name)


__all__ = ["KEEP_SENSOR", "UrdfJointInfo", "apply_asset_options", "keep_links", "urdf_joint_info"]
