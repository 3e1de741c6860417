"""Read a URDF into an ``MjSpec``, keeping what the file says or saying what was dropped.

MuJoCo's URDF parser does the kinematics; around it this module
- resolves ``package://`` and relative mesh paths, converting meshes MuJoCo cannot decode
  (Collada, ...) through the cache of ``meshes.py``;
- checks joint limits MuJoCo would silently drop (lower > upper becomes "unlimited"),
- removes ``<transmission>`` and ``<gazebo>`` (ROS control and Gazebo settings, which
  MuJoCo ignores) with one warning saying what drives the joints instead;
- keeps ``<mimic>`` (MuJoCo writes it as a joint equality ``q = offset + multiplier q_ref``)
  and gives the mimicking joint a zero-gain drive so that no PD drive fights the equality;
- reports errors at the element and line of the user's file, not of the edited copy.
"""

from __future__ import annotations

import re
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco

from ..drives import add_drive
from .asset_errors import AssetError, AssetNotFoundError
from .inertia import bound_massless_links, repair_inertias
from .meshes import convert_mesh, mesh_cache_dir, needs_conversion
from .packages import resolve_package_uri
from .xml_lines import describe, parse_with_lines, serialize_with_lines

_MASSLESS = "mass and inertia of moving bodies must be larger than mjMINVAL"
_LIMITED_TYPES = ("revolute", "prismatic")
_ROS_ONLY = ("transmission", "gazebo")
_COMPILER = ('<mujoco><compiler fusestatic="false" discardvisual="false" strippath="false" '
             'balanceinertia="true"/></mujoco>')
"""Keep every link as its own body (Isaac keeps links as prims) and keep visual geoms
(MuJoCo gives them contype = conaffinity = 0 and group 1: they never collide)."""


class _Where:
    """Names an element of the user's file as ``file:line: <tag name="...">``."""

    def __init__(self, file: Path, lines: dict[ET.Element, int]):
        self.file, self.lines = file, lines
        self.uris: dict[ET.Element, str] = {}
        """The filename a <mesh> had in the file, before it was resolved or converted."""

    def __call__(self, elem: ET.Element) -> str:
        line = self.lines.get(elem)
        name = f'<mesh filename="{self.uris[elem]}">' if elem in self.uris else describe(elem)
        return f"{self.file}:{line}: {name}" if line else f"{self.file}: {name}"


def load_urdf(file: Path, fixed_base: bool) -> mujoco.MjSpec:
    """The robot of URDF ``file``; a free joint ``root_joint`` unless ``fixed_base``."""
    robot, lines = parse_with_lines(file, "URDF")
    if robot.tag != "robot":
        raise AssetError(f"{file}: a URDF's root element must be <robot>, found <{robot.tag}>.")
    where = _Where(file, lines)
    if robot.find("link") is None:
        raise AssetError(f"{file}: the URDF has no <link>: not a robot (a xacro fragment?); "
                         "load the URDF generated from the full xacro.")
    _check_limits(robot, where)
    repair_inertias(robot, where)
    _drop_ros_only(robot, file)
    meshes = _resolve_meshes(robot, file, where)
    mimics = [j.get("name") for j in robot.findall("joint") if j.find("mimic") is not None]
    efforts = {
        joint.get("name"): float(limit.get("effort"))
        for joint in robot.findall("joint")
        if (limit := joint.find("limit")) is not None and limit.get("effort")
    }
    compiler = ET.fromstring(_COMPILER)
    robot.insert(0, compiler)
    spec = _compile(robot, compiler[0], where, meshes)
    root = spec.worldbody.first_body()
    if not fixed_base:
        root.add_freejoint(name="root_joint")
    for name, effort in efforts.items():
        joint = spec.joint(name) if name else None
        if joint is not None and effort > 0:
            joint.actfrcrange = [-effort, effort]
            joint.actfrclimited = mujoco.mjtLimited.mjLIMITED_TRUE
    for name in mimics:
        # the equality moves this joint; a PD drive toward 0 would fight it
        if spec.joint(name) is not None:
            add_drive(spec, name, 0.0, 0.0)
    return spec


def _compile(robot: ET.Element, compiler: ET.Element, where: _Where,
             meshes: dict[str, ET.Element]) -> mujoco.MjSpec:
    """Compile the edited URDF, fixing what MuJoCo rejects but the URDF means (with a warning):
    massless moving links get a bound mass, flat meshes a shell inertia."""
    xml, by_line = serialize_with_lines(robot)
    flat: list[str] = []
    spec = None
    while True:
        try:
            if spec is None:
                spec = mujoco.MjSpec.from_string(xml)
                for name in flat:
                    spec.mesh(name).inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
            spec.compile()
            break
        except (ValueError, mujoco.FatalError) as err:
            message = str(err)
            mesh = re.search(r"mesh volume is too small: (\S+)", message)
            if _MASSLESS in message and compiler.get("boundmass") is None:
                # URDF "virtual" links between the axes of a multi-axis joint, dummy sensor
                # links: MuJoCo needs some mass on each link a joint moves
                bound_massless_links(robot, compiler, where)
                xml, by_line = serialize_with_lines(robot)
                spec = None
            elif mesh and mesh.group(1) not in flat and spec.mesh(mesh.group(1)) is not None:
                # a flat or open mesh has no volume; its inertia (unused: links carry
                # <inertial>) is then that of its surface
                flat.append(mesh.group(1))
                spec.mesh(mesh.group(1)).inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
            else:
                raise AssetError(_explain(message, robot, by_line, where, meshes)) from None
    if flat:
        warnings.warn(f"{where.file.name}: meshes {', '.join(flat)} enclose no volume; MuJoCo "
                      "computes their inertia as shells.", stacklevel=4)
    return spec


def _check_limits(robot: ET.Element, where: _Where) -> None:
    """Inverted limits are an error; missing or empty ranges are kept unlimited, with a warning."""
    missing, empty = [], []
    for joint in robot.findall("joint"):
        if joint.get("type") not in _LIMITED_TYPES:
            continue
        limit = joint.find("limit")
        if limit is None:
            missing.append(joint)
            continue
        try:
            lower, upper = float(limit.get("lower", 0.0)), float(limit.get("upper", 0.0))
        except ValueError:
            raise AssetError(f"{where(limit)}: lower/upper are not numbers; write them in rad "
                             "(revolute) or m (prismatic).") from None
        if lower > upper:
            raise AssetError(
                f"{where(joint)}: lower limit {lower:g} > upper limit {upper:g}; swap them "
                "(MuJoCo would silently make the joint unlimited).")
        if lower == upper:
            empty.append(joint)
            for key in ("lower", "upper"):  # MuJoCo ignores the range anyway, and prints why
                limit.attrib.pop(key, None)
    for joints, what in ((missing, "no <limit> (URDF requires one)"),
                         (empty, "lower == upper, which MuJoCo reads as no limit")):
        if joints:
            names = ", ".join(f"{j.get('name')} (line {where.lines.get(j)})" for j in joints)
            warnings.warn(
                f"{where.file.name}: {len(joints)} revolute/prismatic joints have {what}; ambulo "
                f"leaves them unlimited: {names}. Add <limit lower upper effort velocity/> or make "
                "them type=\"continuous\".", stacklevel=4)


def _drop_ros_only(robot: ET.Element, file: Path) -> None:
    counts = {}
    for tag in _ROS_ONLY:
        for elem in robot.findall(tag):
            robot.remove(elem)
            counts[tag] = counts.get(tag, 0) + 1
    if counts:
        found = " and ".join(f"{n} <{tag}>" for tag, n in counts.items())
        warnings.warn(
            f"{file.name}: ignored {found} (ROS control and Gazebo settings); ambulo drives every "
            "joint with a PD drive capped by its <limit effort> (set gains with DriveDefaults).",
            stacklevel=4)


def _resolve_meshes(robot: ET.Element, file: Path, where: _Where) -> dict[str, ET.Element]:
    """Point every ``<mesh>`` at a file MuJoCo reads; returns the mesh elements by path."""
    by_path: dict[str, ET.Element] = {}
    converted: dict[Path, tuple[Path, bool]] = {}
    for mesh in robot.iter("mesh"):
        uri = mesh.get("filename", "")
        where.uris[mesh] = uri
        path = Path(_resolve_uri(uri, file, where(mesh)))
        if needs_conversion(path):
            if path not in converted:
                try:
                    converted[path] = convert_mesh(path)
                except AssetError as err:
                    raise type(err)(f"{where(mesh)}: {err}") from None
            by_path[str(path)] = mesh
            path = converted[path][0]
        mesh.set("filename", str(path))
        by_path[str(path)] = mesh
    if converted:
        kinds = "/".join(sorted({p.suffix.lower() for p in converted}))
        cached = sum(hit for _, hit in converted.values())
        warnings.warn(
            f"{file.name}: converted {len(converted)} {kinds} meshes MuJoCo cannot read to OBJ "
            f"with trimesh ({cached} already in the cache {mesh_cache_dir()}).", stacklevel=4)
    return by_path


def _resolve_uri(uri: str, urdf_file: Path, element: str) -> str:
    """``package://``, ``file://`` and relative paths (relative to the URDF) as absolute paths."""
    if uri.startswith("package://"):
        try:
            return resolve_package_uri(uri, start=urdf_file)
        except FileNotFoundError as err:
            raise AssetNotFoundError(f"{element}: {err}") from None
    if uri.startswith("file://"):
        uri = uri[len("file://"):]
    path = Path(uri)
    if not path.is_absolute():
        path = urdf_file.parent / path
    if not path.is_file():
        raise AssetNotFoundError(
            f"{element}: mesh {uri!r} not found at {path}; meshes resolve relative to the URDF "
            "file or through package:// (AMBULO_PACKAGE_PATH / ROS_PACKAGE_PATH).")
    return str(path)


def _explain(message: str, robot: ET.Element, by_line: dict[int, ET.Element], where: _Where,
             meshes: dict[str, ET.Element]) -> str:
    """MuJoCo's error as one line naming the element and its line in the user's file."""
    text = "; ".join(line.strip() for line in message.strip().splitlines() if line.strip())
    problem = re.sub(r"^(XML )?Error: ", "", text.split(";")[0].strip())
    elem = None
    if match := re.search(r"Element '[^']*', line (\d+)", text):
        elem = by_line.get(int(match.group(1)))
    elif match := re.search(r"mesh file '([^']*)'", text):
        elem = meshes.get(match.group(1))
    elif match := re.search(r"Element name '([^']*)'", text):
        name = match.group(1)
        elem = next((e for tag in ("link", "joint") for e in robot.findall(tag) if e.get("name") == name), None)
        elem = elem or next((m for path, m in meshes.items() if Path(path).stem == name), None)
    if elem is None or elem not in where.lines:
        return f"{where.file}: cannot be loaded: {text}"
    return f"{where(elem)}: {problem}; fix this element or re-export the URDF."
