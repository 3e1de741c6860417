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

from .asset_options import UrdfJointInfo, apply_asset_options, keep_links, urdf_joint_info
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
    urdf: UrdfJointInfo = field(default_factory=UrdfJointInfo)
    """What the URDF says that the model does not keep (velocity limits, ``dont_collapse`` links)."""
    dof_props: np.ndarray = field(init=False)
    """(num_dofs,) ``DOF_PROPERTIES_DTYPE``: what ``get_asset_dof_properties`` returns."""
    shape_props: list[RigidShapeProperties] = field(init=False)
    """One per collision geom of the asset, in model order (``get/set_asset_rigid_shape_properties``:
    actors created after a set take the new values, as in Isaac Gym)."""

    def __post_init__(self):
        self.dof_props = default_dof_properties(self.model, self.names, self.options, self.urdf.velocity)
        m = self.model
        self.shape_props = [RigidShapeProperties(friction=float(m.geom_friction[g, 0]),
                                                 torsion_friction=float(m.geom_friction[g, 1]),
                                                 rolling_friction=float(m.geom_friction[g, 2]),
                                                 contact_offset=float(m.geom_margin[g]))
                            for g in self.shape_geom_ids.tolist()]

    @property
    def shape_geom_ids(self) -> np.ndarray:
        """Model ids of the asset's collision geoms, in model order (Isaac's shape order)."""
        return collision_geoms(self.model, self.names.body_ids)

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

    def attach(self, spec: mujoco.MjSpec, prim_path: str) -> None:
        """Attach this asset at ``prim_path`` of ``spec`` as its options ask (the batched model
        compiles it exactly as the probe did: same file, drives and option edits)."""
        attach_asset(spec, self.file, prim_path, self.options)


def collision_geoms(model: mujoco.MjModel, body_ids: np.ndarray) -> np.ndarray:
    """Model ids of the geoms of ``body_ids`` that collide (Isaac's shapes: visual meshes are not
    shapes), in model order."""
    collides = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    return np.flatnonzero(np.isin(model.geom_bodyid, body_ids) & collides)


def attach_asset(spec: mujoco.MjSpec, file: str, prim_path: str, options: AssetOptions) -> None:
    add_robot(spec, RobotCfg(file=file, prim_path=prim_path, drives=NO_DRIVE, fixed_base=options.fix_base_link))
    apply_asset_options(spec, prim_path, options)


def load_asset(root: str, file: str, options: AssetOptions | None) -> Asset:
    """Load ``root/file`` (URDF, MJCF or USD) as an Isaac Gym asset."""
    options = options or AssetOptions()
    path = resolve_asset_file(root, file)
    urdf = urdf_joint_info(path)
    spec = new_scene("asset")
    attach_asset(spec, path, PROBE_PRIM, options)
    keep = list(urdf.dont_collapse)
    if options.fix_base_link:  # a welded root has no joint either: keep it a body, not part of the world
        keep += [b.name.removeprefix(PROBE_PRIM + "/") for b in spec.bodies if (b.name or "").startswith(PROBE_PRIM)][:1]
    keep_links(spec, PROBE_PRIM, keep)
    model = spec.compile()
    return Asset(file=path, options=options, model=model, names=EntityNames(model, PROBE_PRIM), urdf=urdf)


def default_dof_properties(model: mujoco.MjModel, names: EntityNames, options: AssetOptions,
                           velocity_limits: dict[str, float] | None = None) -> np.ndarray:
    """Isaac's DOF properties of the asset: limits, friction and armature (at least
    ``options.armature``) from the joints; effort limits from the file's actuators or joint force
    ranges (a URDF's ``<limit effort>``); velocity limits from a URDF's ``<limit velocity>``;
    stiffness and damping from the file's drives (MJCF actuators; zero for a URDF)."""
    joints = names.joint_ids
    props = np.zeros(len(joints), DOF_PROPERTIES_DTYPE)
    if not len(joints):
        return props
    dofs = model.jnt_dofadr[joints]
    props["hasLimits"] = model.jnt_limited[joints].astype(bool)
    props["lower"] = np.where(props["hasLimits"], model.jnt_range[joints, 0], -np.finfo(np.float32).max)
    props["upper"] = np.where(props["hasLimits"], model.jnt_range[joints, 1], np.finfo(np.float32).max)
    props["driveMode"] = options.default_dof_drive_mode
    props["friction"] = model.dof_frictionloss[dofs]
    props["armature"] = np.maximum(model.dof_armature[dofs], options.armature)
    big = np.finfo(np.float32).max
    velocity_limits = velocity_limits or {}
    props["velocity"] = [velocity_limits.get(n, big) for n in names.joint_names]
    props["effort"] = np.where(model.jnt_actfrclimited[joints], model.jnt_actfrcrange[joints, 1], big)
    act_of = {int(model.actuator_trnid[a, 0]): a for a in range(model.nu)}
    for i, j in enumerate(joints.tolist()):
        a = act_of.get(j)
        if a is None:
            continue
        props["stiffness"][i] = -model.actuator_biasprm[a, 1]
        props["damping"][i] = -model.actuator_biasprm[a, 2]
        if model.actuator_forcelimited[a]:
            props["effort"][i] = model.actuator_forcerange[a, 1]
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


__all__ = ["Asset", "NO_DRIVE", "PROBE_PRIM", "attach_asset", "collision_geoms", "default_dof_properties",
           "drive_gains", "load_asset", "resolve_asset_file"]
