"""The data of Isaac's URDF importer (``_urdf``): ``ImportConfig`` and the parsed ``UrdfRobot``.

``ImportConfig`` has Isaac Sim 4.x's defaults; a misspelt setting is an error (Kit's binding
refuses unknown attributes too). ``parse_urdf_file`` reads what scripts inspect or edit before
importing: the robot's name, links (whether each has an ``<inertial>``), joints with their
type, axis, limits, dynamics and the ``drive`` the importer gives them. The physics is loaded
by ``ambulo.core`` when the robot is imported (``urdf_importer``).
"""

from __future__ import annotations

import enum
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field, fields

from ambulo.core.importers.asset_errors import AssetError, AssetNotFoundError
from ambulo.utils.validate import Checked, rule


class UrdfJointTargetType(enum.IntEnum):
    JOINT_DRIVE_NONE = 0
    JOINT_DRIVE_POSITION = 1
    JOINT_DRIVE_VELOCITY = 2


class UrdfJointDriveType(enum.IntEnum):
    JOINT_DRIVE_ACCELERATION = 0
    JOINT_DRIVE_FORCE = 1


class UrdfJointType(enum.IntEnum):
    JOINT_REVOLUTE = 0
    JOINT_CONTINUOUS = 1
    JOINT_PRISMATIC = 2
    JOINT_FIXED = 3
    JOINT_FLOATING = 4
    JOINT_PLANAR = 5


class UrdfNormalSubdivisionScheme(enum.IntEnum):
    CATMULL_CLARK = 0
    LOOP = 1
    BILINEAR = 2
    NONE = 3


@dataclass
class ImportConfig(Checked):
    """Isaac's URDF import settings, with Isaac Sim 4.x's defaults (``set_<name>(value)`` works too).
    Checked when built and again by ``import_urdf``, since scripts set them one by one."""

    merge_fixed_joints: bool = True
    replace_cylinders_with_capsules: bool = False
    convex_decomp: bool = False
    import_inertia_tensor: bool = True
    fix_base: bool = True
    self_collision: bool = False
    density: float = field(default=0.0, metadata=rule(minimum=0))
    """kg/m^3 of links without an <inertial>; 0: MuJoCo's (and PhysX's) 1000."""
    default_drive_type: UrdfJointTargetType = UrdfJointTargetType.JOINT_DRIVE_POSITION
    default_drive_strength: float = field(default=1e3, metadata=rule(minimum=0))
    default_position_drive_damping: float = field(default=1e2, metadata=rule(minimum=0))
    distance_scale: float = field(default=1.0, metadata=rule(minimum=0, strict=True))
    up_vector: tuple = (0.0, 0.0, 1.0)
    create_physics_scene: bool = False
    make_default_prim: bool = False
    subdivision_scheme: UrdfNormalSubdivisionScheme = UrdfNormalSubdivisionScheme.BILINEAR
    make_instanceable: bool = False
    instanceable_usd_path: str = "./instanceable_meshes.usd"
    collision_from_visuals: bool = False
    parse_mimic: bool = True
    override_joint_dynamics: bool = False

    def __getattr__(self, name: str):
        if name.startswith("set_") and name[4:] in _SETTINGS:
            return lambda value: setattr(self, name[4:], value)
        raise AttributeError(f"ImportConfig has no {name!r}; its settings are {', '.join(_SETTINGS)}")

    def __setattr__(self, name: str, value) -> None:
        if name not in _SETTINGS:  # a misspelt setting would otherwise be ignored silently
            raise AttributeError(f"ImportConfig has no setting {name!r}; its settings are {', '.join(_SETTINGS)}")
        object.__setattr__(self, name, value)


_SETTINGS = tuple(f.name for f in fields(ImportConfig))


IGNORED = {
    "import_inertia_tensor": (True, "the URDF's inertia tensors are kept"),
    "convex_decomp": (False, "MuJoCo collides a mesh by its convex hull"),
    "up_vector": ((0.0, 0.0, 1.0), "ambulo's stages are z-up"),
    "make_instanceable": (False, "no instanceable meshes USD is written"),
    "parse_mimic": (True, "mimic joints stay joint equalities"),
    "override_joint_dynamics": (False, "drives take the strength and damping given"),
    "make_default_prim": (False, "the robot is at /<name> but the stage's default prim stays /World"),
}
"""Settings ambulo does not honour: Isaac's default, and what ambulo does instead."""


@dataclass
class UrdfJointDrive:
    target_type: UrdfJointTargetType = UrdfJointTargetType.JOINT_DRIVE_POSITION
    drive_type: UrdfJointDriveType = UrdfJointDriveType.JOINT_DRIVE_FORCE
    strength: float = 0.0
    damping: float = 0.0
    target: float = 0.0


@dataclass
class UrdfJointLimit:
    lower: float = 0.0
    upper: float = 0.0
    effort: float = 0.0
    velocity: float = 0.0


@dataclass
class UrdfJointDynamics:
    damping: float = 0.0
    friction: float = 0.0


@dataclass
class UrdfJoint:
    name: str
    type: UrdfJointType
    parent_link_name: str
    child_link_name: str
    axis: tuple = (1.0, 0.0, 0.0)
    limit: UrdfJointLimit = field(default_factory=UrdfJointLimit)
    dynamics: UrdfJointDynamics = field(default_factory=UrdfJointDynamics)
    drive: UrdfJointDrive = field(default_factory=UrdfJointDrive)
    mimic: str | None = None


@dataclass
class UrdfLink:
    name: str
    has_inertial: bool = False


@dataclass
class UrdfRobot:
    """A parsed URDF: its names, and each joint's ``drive`` that ``import_robot`` applies."""

    name: str = ""
    links: dict = field(default_factory=dict)
    joints: dict = field(default_factory=dict)
    root_link: str = ""
    asset_root: str = ""
    urdf_path: str = ""


def _vector(text: str | None, default: tuple) -> tuple:
    return tuple(float(v) for v in text.split()) if text else default


def initial_drive(config: ImportConfig) -> UrdfJointDrive:
    kind = UrdfJointTargetType(int(config.default_drive_type))
    damping = config.default_position_drive_damping if kind == UrdfJointTargetType.JOINT_DRIVE_POSITION else 0.0
    strength = 0.0 if kind == UrdfJointTargetType.JOINT_DRIVE_NONE else config.default_drive_strength
    return UrdfJointDrive(target_type=kind, strength=float(strength), damping=float(damping))


def _joint(joint: ET.Element, file: str, config: ImportConfig) -> UrdfJoint:
    """The ``UrdfJoint`` of a ``<joint>``; an error naming the joint for one the URDF spec forbids."""
    name, kind = joint.get("name"), joint.get("type", "")
    parent, child = joint.find("parent"), joint.find("child")
    if f"JOINT_{kind.upper()}" not in UrdfJointType.__members__ or parent is None or child is None:
        raise AssetError(f"{file}: <joint name=\"{name}\" type=\"{kind}\"> needs a type of revolute, continuous, "
                         "prismatic, fixed, floating or planar and a <parent> and a <child>; fix the URDF")
    limit, dynamics, mimic, axis = (joint.find(tag) for tag in ("limit", "dynamics", "mimic", "axis"))
    return UrdfJoint(
        name=name, type=UrdfJointType[f"JOINT_{kind.upper()}"],
        parent_link_name=parent.get("link"), child_link_name=child.get("link"),
        axis=_vector(axis.get("xyz") if axis is not None else None, (1.0, 0.0, 0.0)),
        limit=UrdfJointLimit(*(float(limit.get(k, 0.0)) for k in ("lower", "upper", "effort", "velocity")))
        if limit is not None else UrdfJointLimit(),
        dynamics=UrdfJointDynamics(*(float(dynamics.get(k, 0.0)) for k in ("damping", "friction")))
        if dynamics is not None else UrdfJointDynamics(),
        drive=initial_drive(config), mimic=mimic.get("joint") if mimic is not None else None)


def parse_urdf_file(file: str, config: ImportConfig) -> UrdfRobot:
    """The ``UrdfRobot`` of ``file``: names, joint types, limits, dynamics, and the config's drives."""
    if not os.path.isfile(file):
        raise AssetNotFoundError(f"URDF file not found: {file!r}; check urdf_path (relative paths are resolved "
                                 f"from {os.getcwd()!r})")
    try:
        root = ET.parse(file).getroot()
    except ET.ParseError as err:
        raise AssetError(f"{file}: malformed XML ({err}); fix the file or re-export it.") from None
    if root.tag != "robot" or root.find("link") is None:
        raise AssetError(f"{file}: not a URDF robot (the root must be <robot> with <link>s)")
    robot = UrdfRobot(name=root.get("name", "robot"), asset_root=os.path.dirname(os.path.abspath(file)),
                      urdf_path=os.path.basename(file))
    for link in root.findall("link"):
        inertial = link.find("inertial")
        robot.links[link.get("name")] = UrdfLink(link.get("name"),
                                                 inertial is not None and inertial.find("mass") is not None)
    children = set()
    for joint in root.findall("joint"):
        item = _joint(joint, file, config)
        robot.joints[item.name] = item
        children.add(item.child_link_name)
    robot.root_link = next((name for name in robot.links if name not in children), "")
    return robot


__all__ = ["IGNORED", "ImportConfig", "UrdfJoint", "UrdfJointDrive", "UrdfJointDriveType", "UrdfJointDynamics",
           "UrdfJointLimit", "UrdfJointTargetType", "UrdfJointType", "UrdfLink", "UrdfNormalSubdivisionScheme",
           "UrdfRobot", "initial_drive", "parse_urdf_file"]
