"""Isaac Gym assets: a robot file loaded once, with the names and DOF properties Isaac reports.

``load_asset(root, file, options)`` goes through ambulo's importers (URDF, MJCF, USD, with drives)
via ``core.scene.add_robot``, so an asset compiles exactly as it will inside the batched model;
compiling it alone here gives the counts and names scripts ask for before ``prepare_sim``.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from ambulo import assets as bundled
from ambulo.core import DriveDefaults, EntityNames, RobotCfg, add_robot, new_scene

from .types import (
    DOF_MODE_EFFORT,
    DOF_MODE_NONE,
    DOF_MODE_POS,
    DOF_MODE_VEL,
    DOF_PROPERTIES_DTYPE,
    AssetOptions,
    RigidBodyProperties,
    RigidShapeProperties,
    Vec3,
)

log = logging.getLogger(__name__)

PROBE_PRIM = "/World/asset"
"""Where an asset is attached when it is compiled alone to read its names and properties."""

NO_DRIVE = DriveDefaults(stiffness=0.0, damping=0.0)
"""Gains of joints that arrive without an actuator: zero, as Isaac Gym loads URDF joints (a
script sets stiffness and damping through the DOF properties)."""


def resolve_asset_file(root: str, file: str) -> str:
    """``root/file`` if it exists; else the bundled asset named like ``file`` (the tutorials'
    ``assets/humanoid.urdf`` is ambulo's ``humanoid``), with a warning; else a one-line error."""
    path = os.path.join(root, file)
    if os.path.isfile(path):
        return path
    stem = Path(file).stem
    if stem in bundled.names():
        log.warning("isaacgym: %s not found; loading ambulo's bundled %r (%s) instead",
                    path, stem, os.path.basename(bundled.path(stem)))
        return bundled.path(stem)
    raise FileNotFoundError(f"isaacgym load_asset: no file {path!r} (root {root!r}, relative to "
                            f"{os.getcwd()!r}); bundled assets that stand in by name: {', '.join(bundled.names())}")


@dataclass
class Asset:
    """A loaded robot file: what ``load_asset`` returns, and what ``create_actor`` places."""

    file: str
    options: AssetOptions
    model: mujoco.MjModel
    """The asset compiled alone (at ``PROBE_PRIM``)."""
    names: EntityNames
    dof_props: np.ndarray = field(init=False)
    """(num_dofs,) ``DOF_PROPERTIES_DTYPE``: what ``get_asset_dof_properties`` returns."""
    shape_props: list[RigidShapeProperties] = field(init=False)
    """One per collision geom of the asset, in model order (``get/set_asset_rigid_shape_properties``:
    actors created after a set take the new values, as in Isaac Gym)."""

    def __post_init__(self):
        self.dof_props = default_dof_properties(self.model, self.names, self.options.default_dof_drive_mode)
        m = self.model
        self.shape_props = [RigidShapeProperties(friction=float(m.geom_friction[g, 0]),
                                                 torsion_friction=float(m.geom_friction[g, 1]),
                                                 rolling_friction=float(m.geom_friction[g, 2]),
                                                 contact_offset=float(m.geom_margin[g]))
                            for g in self.shape_geom_ids.tolist()]

    @property
    def shape_geom_ids(self) -> np.ndarray:
        """Model ids of the asset's geoms, in model order (Isaac's shape order)."""
        return np.flatnonzero(np.isin(self.model.geom_bodyid, self.names.body_ids))

    def body_properties(self) -> list[RigidBodyProperties]:
        """Each body's mass (kg), centre of mass in the body frame (m) and inertia about it (kg m^2)."""
        m = self.model
        return [RigidBodyProperties(mass=float(m.body_mass[b]), com=Vec3(*m.body_ipos[b]),
                                    inertia=np.diag(m.body_inertia[b])) for b in self.names.body_ids.tolist()]

    @property
    def dof_names(self) -> list[str]:
        return self.names.joint_names

    @property
    def body_names(self) -> list[str]:
        return self.names.body_names

    @property
    def num_dofs(self) -> int:
        return len(self.names.joint_names)

    @property
    def num_bodies(self) -> int:
        return len(self.names.body_names)

    @property
    def num_shapes(self) -> int:
        return len(self.shape_geom_ids)

    def robot_cfg(self, prim_path: str) -> RobotCfg:
        """How the batched model attaches this asset at ``prim_path``."""
        return RobotCfg(file=self.file, prim_path=prim_path, drives=NO_DRIVE, fixed_base=self.options.fix_base_link)


def load_asset(root: str, file: str, options: AssetOptions | None) -> Asset:
    """Load ``root/file`` (URDF, MJCF or USD) as an Isaac Gym asset."""
    options = options or AssetOptions()
    path = resolve_asset_file(root, file)
    spec = new_scene("asset")
    add_robot(spec, RobotCfg(file=path, prim_path=PROBE_PRIM, drives=NO_DRIVE, fixed_base=options.fix_base_link))
    model = spec.compile()
    return Asset(file=path, options=options, model=model, names=EntityNames(model, PROBE_PRIM))


def default_dof_properties(model: mujoco.MjModel, names: EntityNames, drive_mode: int) -> np.ndarray:
    """Isaac's DOF properties of the asset: limits, armature and friction from the joints;
    stiffness, damping and effort limits from the file's drives (MJCF actuators; zero for a URDF)."""
    joints = names.joint_ids
    props = np.zeros(len(joints), DOF_PROPERTIES_DTYPE)
    if not len(joints):
        return props
    dofs = model.jnt_dofadr[joints]
    props["hasLimits"] = model.jnt_limited[joints].astype(bool)
    props["lower"] = np.where(props["hasLimits"], model.jnt_range[joints, 0], -np.finfo(np.float32).max)
    props["upper"] = np.where(props["hasLimits"], model.jnt_range[joints, 1], np.finfo(np.float32).max)
    props["driveMode"] = drive_mode
    props["friction"] = model.dof_frictionloss[dofs]
    props["armature"] = model.dof_armature[dofs]
    props["velocity"] = np.finfo(np.float32).max
    act_of = {int(model.actuator_trnid[a, 0]): a for a in range(model.nu)}
    for i, j in enumerate(joints.tolist()):
        a = act_of.get(j)
        if a is None:
            continue
        props["stiffness"][i] = -model.actuator_biasprm[a, 1]
        props["damping"][i] = -model.actuator_biasprm[a, 2]
        if model.actuator_forcelimited[a]:
            props["effort"][i] = model.actuator_forcerange[a, 1]
        else:
            props["effort"][i] = np.finfo(np.float32).max
    return props


def drive_gains(props: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(kp, kd) of ambulo's drives for Isaac DOF properties: position mode drives to the position
    target with stiffness and damping, velocity mode to the velocity target with damping only;
    effort and none modes turn the drive off (PhysX's drive is disabled there)."""
    mode = props["driveMode"]
    unknown = ~np.isin(mode, (DOF_MODE_NONE, DOF_MODE_POS, DOF_MODE_VEL, DOF_MODE_EFFORT))
    if unknown.any():
        raise ValueError(f"unknown driveMode {int(mode[unknown][0])}; use gymapi.DOF_MODE_NONE, DOF_MODE_POS, "
                         "DOF_MODE_VEL or DOF_MODE_EFFORT")
    kp = np.where(mode == DOF_MODE_POS, props["stiffness"], 0.0)
    kd = np.where((mode == DOF_MODE_POS) | (mode == DOF_MODE_VEL), props["damping"], 0.0)
    return kp.astype(np.float64), kd.astype(np.float64)


__all__ = ["Asset", "NO_DRIVE", "PROBE_PRIM", "default_dof_properties", "drive_gains", "load_asset",
           "resolve_asset_file"]
