"""Isaac's URDF importer (``isaacsim.asset.importer.urdf._urdf``, ``omni.importer.urdf._urdf``,
``omni.isaac.urdf._urdf``): its interface and Kit commands, on ambulo's URDF loader (the
``ImportConfig`` and ``UrdfRobot`` data are in ``urdf_types``).

``parse_urdf`` reads the robot's names (links, joints, their types, limits and drives: what
scripts edit before importing); ``import_robot`` places the URDF on the stage at
``<default prim>/<robot name>`` (``/<robot name>`` with ``make_default_prim``) through the same
``ambulo.core.add_robot`` every ambulo robot goes through, so the returned prim path works with
``Articulation``/``ArticulationView``/``Robot``. A URDF imported before the ``World`` exists is
added to the World's model when the World is created.

The ``ImportConfig`` (Isaac 4.x defaults) is honoured where MuJoCo has a meaning: ``fix_base``
(no free joint), ``merge_fixed_joints`` (links on fixed joints fused into their parent, masses
and inertias combined), ``default_drive_type``/``default_drive_strength``/
``default_position_drive_damping`` and each joint's ``drive`` (position: kp = strength, kd =
damping; velocity: kp = 0, kd = strength; none: 0, 0; SI units, N*m/rad or N/m),
``self_collision`` (off: contacts between the robot's links excluded), ``density`` (links without
an ``<inertial>``), ``collision_from_visuals``, ``replace_cylinders_with_capsules``,
``create_physics_scene`` and ``distance_scale`` when it matches the stage's units. Any other
setting that differs from Isaac's default gets one warning naming it.
"""

from __future__ import annotations

import os
import re
import tempfile
import warnings

import mujoco

from ambulo.core import DriveDefaults, RobotCfg, add_robot, geom_collides, is_drive
from ambulo.core.usd_physx import _exclude_self_collisions
from ambulo.sim.current import current_world_or_none
from ambulo.sim.usd_stage import current_usd_stage
from ambulo.utils.validate import check_fields

from .kit_commands import Command, execute
from .omni_usd import get_stage_next_free_path
from .urdf_types import (
    IGNORED,
    ImportConfig,
    UrdfJointDrive,
    UrdfJointTargetType,
    UrdfJointType,
    UrdfRobot,
    initial_drive,
    parse_urdf_file,
)
from .usd_edit import place_model_frame


def _valid_identifier(name: str) -> str:
    """Kit's prim name for a robot: characters USD does not allow become "_" (then "a" goes first)."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", name) or "robot"
    return "a" + name if name[0] == "_" or name[0].isdigit() else name


def _warn_ignored(robot: UrdfRobot, config: ImportConfig, dest: str, meters_per_unit: float) -> None:
    ignored = [f"{key}={getattr(config, key)!r} ({why})" for key, (default, why) in IGNORED.items()
               if getattr(config, key) != default]
    if abs(config.distance_scale * meters_per_unit - 1.0) > 1e-9:
        ignored.append(f"distance_scale={config.distance_scale!r} (the robot keeps its URDF size in metres; "
                       f"the stage is {meters_per_unit:g} m per unit)")
    if dest:
        ignored.append(f"dest_path={dest!r} (no USD file is written: the robot is imported onto the open stage)")
    if ignored:
        warnings.warn(f"URDF import of {robot.name}: ambulo does not honour " + "; ".join(ignored), stacklevel=4)


def _gains(drive: UrdfJointDrive) -> tuple[float, float]:
    """(kp, kd) of Isaac's joint drive: a position drive's stiffness and damping, a velocity drive's damping."""
    kind = UrdfJointTargetType(int(drive.target_type))
    if kind == UrdfJointTargetType.JOINT_DRIVE_POSITION:
        return float(drive.strength), float(drive.damping)
    if kind == UrdfJointTargetType.JOINT_DRIVE_VELOCITY:
        return 0.0, float(drive.strength)
    return 0.0, 0.0


def _set_gains(spec, name: str, kp: float, kd: float) -> None:
    """The ambulo drive of joint ``name`` (``core.drives``: bias (0, -kp, -kd)) with new gains."""
    actuator = spec.actuator(name)
    if actuator is not None and is_drive(actuator):
        actuator.biasprm[1:3] = [-kp, -kd]


def _robot_bodies(spec, prim_path: str) -> list:
    return [b for b in spec.bodies if b.name.startswith(prim_path + "/")]


def _fuse_fixed_links(spec, prim_path: str) -> None:
    """Links on fixed joints become part of their parent link (MuJoCo fuses their geoms, masses, inertias)."""
    bodies = _robot_bodies(spec, prim_path)
    inside = {b.name for b in bodies}
    targets = {b.name for b in bodies if not list(b.joints) and b.parent.name in inside}
    if not targets:
        return
    flags = {b.name: b.fuse for b in spec.bodies}
    for body in spec.bodies:
        body.fuse = int(body.name in targets)
    spec.fuse_static()
    for body in spec.bodies:
        body.fuse = flags[body.name]


def _attach(world, file: str, robot: UrdfRobot, config: ImportConfig, prim_path: str) -> None:
    """Add the URDF to the World's model at ``prim_path`` with the import settings."""
    if not world.usd.stage.GetPrimAtPath(prim_path).IsValid():
        return  # deleted before the World adopted the stage
    spec = world.sim.spec
    kp, kd = _gains(initial_drive(config))
    frame = add_robot(spec, RobotCfg(file=file, prim_path=prim_path, fixed_base=bool(config.fix_base),
                                     drives=DriveDefaults(stiffness=kp, damping=kd))).frame
    place_model_frame(frame, world.usd.stage.GetPrimAtPath(prim_path), world.stage_units_in_meters)  # moved before
    for joint in robot.joints.values():
        if joint.mimic is None and joint.type != UrdfJointType.JOINT_FIXED:
            _set_gains(spec, f"{prim_path}/{joint.name}", *_gains(joint.drive))
    for body in _robot_bodies(spec, prim_path):
        link = robot.links.get(body.name[len(prim_path) + 1:])
        geoms = list(body.geoms)
        if config.collision_from_visuals and not any(geom_collides(g) for g in geoms):
            for geom in geoms:
                geom.contype = geom.conaffinity = 1
        if config.replace_cylinders_with_capsules:
            for geom in geoms:
                if geom.type == mujoco.mjtGeom.mjGEOM_CYLINDER:
                    geom.type = mujoco.mjtGeom.mjGEOM_CAPSULE
        if config.density > 0 and link is not None and not link.has_inertial and any(geom_collides(g) for g in geoms):
            for geom in geoms:  # PhysX weighs a link's collision shapes, not its visuals
                geom.density = float(config.density) if geom_collides(geom) else 0.0
    if config.merge_fixed_joints:
        _fuse_fixed_links(spec, prim_path)
    if not config.self_collision:
        _exclude_self_collisions(spec, prim_path)
    _mirror(world.usd, spec, prim_path)


def _mirror(usd, spec, prim_path: str) -> None:
    """Placeholder prims for the robot and its links (``UsdStage.mirror_spec`` does only ``/World/...``)."""
    names = {prim_path} | {b.name for b in _robot_bodies(spec, prim_path)}
    for name in sorted(names):
        if not usd.stage.GetPrimAtPath(name).IsValid():
            usd.mirror(name)


def _physics_scene(stage, config: ImportConfig) -> None:
    from pxr import Gf, UsdPhysics

    if any(prim.IsA(UsdPhysics.Scene) for prim in stage.Traverse()):
        return
    scene = UsdPhysics.Scene.Define(stage, "/physicsScene")
    scene.CreateGravityDirectionAttr().Set(Gf.Vec3f(0.0, 0.0, -1.0))
    scene.CreateGravityMagnitudeAttr().Set(9.81 * float(config.distance_scale))


def import_urdf(robot: UrdfRobot, config: ImportConfig, dest: str = "") -> str:
    """Place ``robot`` on the stage as Kit's importer does; returns its prim path."""
    check_fields(config)  # set one by one (set_density(-1)) after it was built
    file = os.path.join(robot.asset_root, robot.urdf_path)
    usd = current_usd_stage()
    stage = usd.stage
    _warn_ignored(robot, config, dest, usd.meters_per_unit)
    name = _valid_identifier(robot.name)
    base = f"/{name}" if config.make_default_prim else f"{stage.GetDefaultPrim().GetPath()}/{name}"
    prim_path = get_stage_next_free_path(stage, base, False)
    if config.create_physics_scene:
        _physics_scene(stage, config)
    usd.mirror(prim_path)
    world = current_world_or_none()
    if world is not None:
        _attach(world, file, robot, config, prim_path)
    else:
        usd.on_adopt.append(lambda w: _attach(w, file, robot, config, prim_path))
        for link in robot.links:  # the links are prims at once, as in Kit
            usd.mirror(f"{prim_path}/{link}")
    return prim_path


class Urdf:
    """The URDF interface (``_urdf.acquire_urdf_interface()``)."""

    def parse_urdf(self, asset_root: str, asset_name: str, import_config: ImportConfig | None = None) -> UrdfRobot:
        return parse_urdf_file(os.path.join(asset_root, asset_name), import_config or ImportConfig())

    def parse_string_urdf(self, urdf_str: str, import_config: ImportConfig | None = None) -> UrdfRobot:
        """Parse URDF text (kept in a temporary file: its meshes must have absolute paths)."""
        folder = tempfile.mkdtemp(prefix="ambulo-urdf-")
        with open(os.path.join(folder, "robot.urdf"), "w") as out:
            out.write(urdf_str)
        return parse_urdf_file(os.path.join(folder, "robot.urdf"), import_config or ImportConfig())

    def import_robot(self, asset_root: str, asset_name: str, robot: UrdfRobot | None = None,
                     import_config: ImportConfig | None = None, stage_identifier: str = "",
                     get_articulation_root: bool = False) -> str:
        """Import ``robot`` (parsed from ``asset_root/asset_name`` if None); returns its prim path, which
        is also ambulo's articulation root (``get_articulation_root`` gives the same path)."""
        config = import_config or ImportConfig()
        if robot is None or not robot.urdf_path:
            robot = self.parse_urdf(asset_root, asset_name, config)
        return import_urdf(robot, config, stage_identifier)


_INTERFACE = Urdf()


def acquire_urdf_interface() -> Urdf:
    return _INTERFACE


def release_urdf_interface(interface: Urdf) -> None:
    """Kit unloads the plugin; ambulo's interface has nothing to release."""


# -- the Kit commands -----------------------------------------------------------------
class URDFCreateImportConfig(Command):
    """A new ``ImportConfig`` with Isaac's defaults."""

    def do(self) -> ImportConfig:
        return ImportConfig()


class URDFParseFile(Command):
    """Parse ``urdf_path``; returns the ``UrdfRobot`` (edit its joints' ``drive`` before importing)."""

    def __init__(self, urdf_path: str = "", import_config: ImportConfig | None = None):
        self._path, self._config = os.path.abspath(urdf_path), import_config or ImportConfig()

    def do(self) -> UrdfRobot:
        return parse_urdf_file(self._path, self._config)


class URDFParseText(Command):
    def __init__(self, urdf_string: str = "", import_config: ImportConfig | None = None):
        self._text, self._config = urdf_string, import_config or ImportConfig()

    def do(self) -> UrdfRobot:
        return _INTERFACE.parse_string_urdf(self._text, self._config)


class URDFImportRobot(Command):
    """Import a parsed ``urdf_robot`` onto the stage; returns its prim path."""

    def __init__(self, urdf_path: str = "", urdf_robot: UrdfRobot | None = None, import_config=None,
                 dest_path: str = "", get_articulation_root: bool = False):
        self._path, self._robot, self._config, self._dest = urdf_path, urdf_robot, import_config, dest_path

    def do(self) -> str:
        root, name = os.path.split(os.path.abspath(self._path)) if self._path else ("", "")
        return _INTERFACE.import_robot(root, name, self._robot, self._config or ImportConfig(), self._dest)


class URDFParseAndImportFile(Command):
    """Parse ``urdf_path`` and import it; returns the robot's prim path."""

    def __init__(self, urdf_path: str = "", import_config=None, dest_path: str = "",
                 get_articulation_root: bool = False):
        self._path, self._config, self._dest = urdf_path, import_config or ImportConfig(), dest_path

    def do(self) -> str:
        _, robot = execute("URDFParseFile", urdf_path=self._path, import_config=self._config)
        return import_urdf(robot, self._config, self._dest)


COMMANDS = ("URDFCreateImportConfig", "URDFImportRobot", "URDFParseAndImportFile", "URDFParseFile", "URDFParseText")
"""The command classes the importer's package exports (``from isaacsim.asset.importer.urdf import ...``)."""

__all__ = ["Urdf", "acquire_urdf_interface", "import_urdf", "release_urdf_interface"]
