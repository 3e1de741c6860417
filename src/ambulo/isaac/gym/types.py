"""Isaac Gym's value types: ``Vec3``, ``Quat`` (x, y, z, w), ``Transform`` and the parameter structs.

These mirror Isaac Gym's pybind structs, which scripts build empty and then assign field by field
(``sim_params.physx.num_position_iterations = 4``); so they are plain mutable dataclasses with
Isaac's defaults, checked when they are used (``Gym.create_sim`` turns ``SimParams`` into a
``core.PhysicsCfg``, which is a checked config) rather than field by field here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

# Isaac Gym's enums (values as in gymapi, so scripts that store or compare the ints keep working)
UP_AXIS_Y, UP_AXIS_Z = 0, 1
SIM_PHYSX, SIM_FLEX = 0, 1
DOF_MODE_NONE, DOF_MODE_POS, DOF_MODE_VEL, DOF_MODE_EFFORT = 0, 1, 2, 3
DOF_INVALID, DOF_ROTATION, DOF_TRANSLATION = -1, 0, 1


class Vec3:
    """A 3-vector with Isaac Gym's attributes (``x``, ``y``, ``z``) and operators."""

    __slots__ = ("x", "y", "z")

    def __init__(self, x: float = 0.0, y: float = 0.0, z: float = 0.0):
        self.x, self.y, self.z = float(x), float(y), float(z)

    def __add__(self, other: Vec3) -> Vec3:
        return Vec3(self.x + other.x, self.y + other.y, self.z + other.z)

    def __sub__(self, other: Vec3) -> Vec3:
        return Vec3(self.x - other.x, self.y - other.y, self.z - other.z)

    def __mul__(self, s: float) -> Vec3:
        return Vec3(self.x * s, self.y * s, self.z * s)

    __rmul__ = __mul__

    def __truediv__(self, s: float) -> Vec3:
        return Vec3(self.x / s, self.y / s, self.z / s)

    def __neg__(self) -> Vec3:
        return Vec3(-self.x, -self.y, -self.z)

    def __eq__(self, other) -> bool:
        return isinstance(other, Vec3) and (self.x, self.y, self.z) == (other.x, other.y, other.z)

    def __repr__(self) -> str:
        return f"Vec3({self.x:g}, {self.y:g}, {self.z:g})"

    def dot(self, other: Vec3) -> float:
        return self.x * other.x + self.y * other.y + self.z * other.z

    def cross(self, other: Vec3) -> Vec3:
        return Vec3(*np.cross(self.as_array(), other.as_array()))

    def length(self) -> float:
        return math.sqrt(self.dot(self))

    def normalize(self) -> Vec3:
        return self / self.length()

    def as_array(self) -> np.ndarray:
        """(3,) float64 (not an Isaac method: what ambulo reads a Vec3 with)."""
        return np.array([self.x, self.y, self.z])


class Quat:
    """A rotation quaternion in Isaac Gym's order: ``Quat(x, y, z, w)``, identity ``Quat(0, 0, 0, 1)``."""

    __slots__ = ("x", "y", "z", "w")

    def __init__(self, x: float = 0.0, y: float = 0.0, z: float = 0.0, w: float = 1.0):
        self.x, self.y, self.z, self.w = float(x), float(y), float(z), float(w)

    @classmethod
    def from_axis_angle(cls, axis: Vec3, angle: float) -> Quat:
        a = axis.normalize() * math.sin(0.5 * angle)
        return cls(a.x, a.y, a.z, math.cos(0.5 * angle))

    @classmethod
    def from_euler_zyx(cls, roll: float, pitch: float, yaw: float) -> Quat:
        """Rotation ``Rz(yaw) Ry(pitch) Rx(roll)``, as Isaac Gym's ``Quat.from_euler_zyx``."""
        cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
        cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
        cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
        return cls(sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                   cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy)

    def to_euler_zyx(self) -> tuple[float, float, float]:
        """(roll, pitch, yaw) rad of ``from_euler_zyx``."""
        x, y, z, w = self.x, self.y, self.z, self.w
        roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
        pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
        yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        return roll, pitch, yaw

    def __mul__(self, q: Quat) -> Quat:
        x1, y1, z1, w1 = self.x, self.y, self.z, self.w
        x2, y2, z2, w2 = q.x, q.y, q.z, q.w
        return Quat(w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                    w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2)

    def __eq__(self, other) -> bool:
        return isinstance(other, Quat) and (self.x, self.y, self.z, self.w) == (other.x, other.y, other.z, other.w)

    def __repr__(self) -> str:
        return f"Quat({self.x:g}, {self.y:g}, {self.z:g}, {self.w:g})"

    def inverse(self) -> Quat:
        return Quat(-self.x, -self.y, -self.z, self.w)

    def normalize(self) -> Quat:
        n = math.sqrt(self.x ** 2 + self.y ** 2 + self.z ** 2 + self.w ** 2)
        return Quat(self.x / n, self.y / n, self.z / n, self.w / n)

    def rotate(self, v: Vec3) -> Vec3:
        u = Vec3(self.x, self.y, self.z)
        t = u.cross(v) * 2.0
        return v + t * self.w + u.cross(t)

    def as_wxyz(self) -> np.ndarray:
        """(4,) float64 in MuJoCo's (w, x, y, z) order (not an Isaac method)."""
        return np.array([self.w, self.x, self.y, self.z])


class Transform:
    """A pose: position ``p`` (Vec3) and rotation ``r`` (Quat)."""

    __slots__ = ("p", "r")

    def __init__(self, p: Vec3 | None = None, r: Quat | None = None):
        self.p = Vec3() if p is None else p
        self.r = Quat() if r is None else r

    def transform_point(self, v: Vec3) -> Vec3:
        return self.r.rotate(v) + self.p

    def transform_vector(self, v: Vec3) -> Vec3:
        return self.r.rotate(v)

    def inverse(self) -> Transform:
        r = self.r.inverse()
        return Transform(-r.rotate(self.p), r)

    def __mul__(self, other: Transform) -> Transform:
        return Transform(self.transform_point(other.p), self.r * other.r)

    def __repr__(self) -> str:
        return f"Transform(p={self.p!r}, r={self.r!r})"


@dataclass
class PhysXParams:
    """``SimParams.physx``. ambulo's engines are MuJoCo, so ``create_sim`` maps what has a meaning
    there (``num_threads`` -> the CPU engine's threads) and records the rest (see
    docs/isaac-gym-coverage.md)."""

    solver_type: int = 1
    num_position_iterations: int = 4
    num_velocity_iterations: int = 1
    contact_offset: float = 0.02
    rest_offset: float = 0.001
    bounce_threshold_velocity: float = 0.2
    max_depenetration_velocity: float = 100.0
    friction_offset_threshold: float = 0.04
    friction_correlation_distance: float = 0.025
    default_buffer_size_multiplier: float = 2.0
    max_gpu_contact_pairs: int = 1024 * 1024
    num_subscenes: int = 0
    num_threads: int = 0
    use_gpu: bool = False
    always_use_articulations: bool = False
    contact_collection: int = 2


@dataclass
class FlexParams:
    """``SimParams.flex``: accepted and unused (ambulo has no Flex backend; ``SIM_FLEX`` fails)."""

    solver_type: int = 5
    num_outer_iterations: int = 4
    num_inner_iterations: int = 15
    relaxation: float = 0.75
    warm_start: float = 0.4


@dataclass
class SimParams:
    """Isaac Gym's ``SimParams`` with its defaults (y up, 60 Hz, 2 substeps, CPU pipeline)."""

    dt: float = 1.0 / 60.0
    substeps: int = 2
    up_axis: int = UP_AXIS_Y
    gravity: Vec3 = field(default_factory=lambda: Vec3(0.0, -9.80665, 0.0))
    num_client_threads: int = 0
    use_gpu_pipeline: bool = False
    enable_actor_creation_warning: bool = False
    stress_visualization: bool = False
    physx: PhysXParams = field(default_factory=PhysXParams)
    flex: FlexParams = field(default_factory=FlexParams)


@dataclass
class AssetOptions:
    """Isaac Gym's ``AssetOptions`` (defaults as gymapi's)."""

    fix_base_link: bool = False
    default_dof_drive_mode: int = DOF_MODE_NONE
    disable_gravity: bool = False
    armature: float = 0.0
    density: float = 1000.0
    angular_damping: float = 0.5
    linear_damping: float = 0.0
    max_angular_velocity: float = 64.0
    max_linear_velocity: float = 1000.0
    thickness: float = 0.02
    collapse_fixed_joints: bool = False
    flip_visual_attachments: bool = False
    replace_cylinder_with_capsule: bool = False
    override_com: bool = False
    override_inertia: bool = False
    use_mesh_materials: bool = False
    mesh_normal_mode: int = 0
    convex_decomposition_from_submeshes: bool = False
    vhacd_enabled: bool = False
    slices_per_cylinder: int = 20
    enable_gyroscopic_forces: bool = True


@dataclass
class PlaneParams:
    """The ground plane: ``normal`` must be the up axis (z) here; frictions and restitution apply."""

    normal: Vec3 = field(default_factory=lambda: Vec3(0.0, 0.0, 1.0))
    distance: float = 0.0
    static_friction: float = 1.0
    dynamic_friction: float = 1.0
    restitution: float = 0.0
    segmentation_id: int = 0


@dataclass
class HeightFieldParams:
    """``add_heightfield``'s terrain: samples ``[i, j]`` (i along x, ``nbColumns`` of them, spaced
    ``column_scale`` m; j along y, ``nbRows``, ``row_scale`` m; as legged_gym fills them), each
    ``vertical_scale`` m per unit, placed by ``transform`` (its position; rotation must be identity)."""

    column_scale: float = 1.0
    row_scale: float = 1.0
    vertical_scale: float = 1.0
    nbRows: int = 0
    nbColumns: int = 0
    transform: Transform = field(default_factory=Transform)
    static_friction: float = 1.0
    dynamic_friction: float = 1.0
    restitution: float = 0.0
    segmentation_id: int = 0


@dataclass
class TriangleMeshParams:
    """``add_triangle_mesh``'s terrain: ``nb_vertices`` vertices and ``nb_triangles`` triangles,
    placed by ``transform`` (its position; rotation must be identity)."""

    nb_vertices: int = 0
    nb_triangles: int = 0
    transform: Transform = field(default_factory=Transform)
    static_friction: float = 1.0
    dynamic_friction: float = 1.0
    restitution: float = 0.0
    segmentation_id: int = 0


@dataclass
class CameraProperties:
    """Isaac Gym's ``CameraProperties`` (used by the headless viewer and camera sensors)."""

    width: int = 1920
    height: int = 1080
    horizontal_fov: float = 90.0
    near_plane: float = 0.1
    far_plane: float = 1000.0
    enable_tensors: bool = False
    use_collision_geometry: bool = False
    supersampling_horizontal: int = 1
    supersampling_vertical: int = 1


class _FloatFields:
    """Isaac's property structs are pybind classes whose float fields convert what they are given
    (legged_gym assigns a one-element torch tensor to ``friction``); these do the same on assignment."""

    _FLOATS: tuple[str, ...] = ()

    def __setattr__(self, name, value):
        if name in self._FLOATS and not isinstance(value, float):
            value = float(value)
        super().__setattr__(name, value)


@dataclass
class RigidShapeProperties(_FloatFields):
    """One shape's contact properties (``get_actor_rigid_shape_properties``)."""

    _FLOATS = ("friction", "rolling_friction", "torsion_friction", "restitution", "contact_offset", "rest_offset",
               "compliance", "thickness")

    friction: float = 1.0
    rolling_friction: float = 0.0
    torsion_friction: float = 0.0
    restitution: float = 0.0
    contact_offset: float = 0.0
    rest_offset: float = 0.0
    filter: int = 0
    compliance: float = 0.0
    thickness: float = 0.0


@dataclass
class RigidBodyProperties(_FloatFields):
    """One body's mass properties (``get_actor_rigid_body_properties``)."""

    _FLOATS = ("mass",)

    mass: float = 0.0
    com: Vec3 = field(default_factory=Vec3)
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    flags: int = 0


_IGNORED = "accepted and not used: MuJoCo has no counterpart"
ISAAC_APPROXIMATED: dict[str, str] = {
    **{f"PhysXParams.{name}": _IGNORED for name in (
        "solver_type", "num_position_iterations", "num_velocity_iterations", "bounce_threshold_velocity",
        "max_depenetration_velocity", "friction_offset_threshold", "friction_correlation_distance",
        "default_buffer_size_multiplier", "max_gpu_contact_pairs", "num_subscenes", "use_gpu",
        "always_use_articulations", "contact_collection")},
    "PhysXParams.contact_offset": "not mapped: MuJoCo contacts act across a geom's whole margin, so a margin "
                                  "would hold shapes this far apart; contacts start at touching",
    "PhysXParams.rest_offset": "not mapped: shapes rest touching (slightly interpenetrating: soft contacts), "
                               "as with rest_offset 0",
    "PhysXParams.num_threads": "the CPU engine's thread count (0: every CPU)",
    "SimParams.substeps": "MuJoCo steps per simulate; the MuJoCo timestep is dt / substeps",
    "SimParams.up_axis": "UP_AXIS_Z only (UP_AXIS_Y fails at create_sim)",
    "SimParams.use_gpu_pipeline": "tensors and MuJoCo Warp on cuda:<compute device> when CUDA is present, else the CPU",
    **{f"SimParams.{name}": _IGNORED for name in ("num_client_threads", "enable_actor_creation_warning",
                                                  "stress_visualization", "flex")},
    **{f"AssetOptions.{name}": _IGNORED for name in (
        "angular_damping", "linear_damping", "max_angular_velocity", "max_linear_velocity", "density",
        "thickness", "override_com", "override_inertia", "use_mesh_materials", "mesh_normal_mode", "disable_gravity",
        "convex_decomposition_from_submeshes", "vhacd_enabled", "slices_per_cylinder", "enable_gyroscopic_forces")},
    "AssetOptions.armature": "the DOFs' armature is at least this (MuJoCo dof armature; a file's larger one is kept)",
    "AssetOptions.collapse_fixed_joints": "MuJoCo's fusestatic: links on fixed joints merge into their parent body; "
                                          "URDF joints with dont_collapse=\"true\" keep their child link",
    "AssetOptions.replace_cylinder_with_capsule": "collision cylinders become capsules of the same radius and "
                                                  "cylinder length (so 2 radii longer overall)",
    "AssetOptions.flip_visual_attachments": "accepted: visual meshes keep the file's frames (they are only drawn)",
    "PlaneParams.normal": "+z only",
    "PlaneParams.static_friction": "kept, not used: MuJoCo has one sliding friction, dynamic_friction",
    "PlaneParams.segmentation_id": _IGNORED,
}
"""Fields of Isaac Gym's structs that ambulo maps differently or ignores -> how."""

DOF_PROPERTIES_DTYPE = np.dtype([
    ("hasLimits", "?"), ("lower", "f4"), ("upper", "f4"), ("driveMode", "i4"), ("velocity", "f4"),
    ("effort", "f4"), ("stiffness", "f4"), ("damping", "f4"), ("friction", "f4"), ("armature", "f4"),
])
"""Isaac Gym's DOF properties record (a numpy structured array with these fields)."""

DOF_STATE_DTYPE = np.dtype([("pos", "f4"), ("vel", "f4")])
"""Isaac Gym's ``DofState`` record (``get_actor_dof_states``)."""

__all__ = [
    "AssetOptions", "CameraProperties", "DOF_INVALID", "ISAAC_APPROXIMATED", "DOF_MODE_EFFORT", "DOF_MODE_NONE", "DOF_MODE_POS",
    "DOF_MODE_VEL", "DOF_PROPERTIES_DTYPE", "DOF_ROTATION", "DOF_STATE_DTYPE", "DOF_TRANSLATION", "FlexParams",
    "HeightFieldParams", "PhysXParams", "PlaneParams", "Quat", "RigidBodyProperties", "RigidShapeProperties", "SIM_FLEX", "SIM_PHYSX",
    "SimParams", "Transform", "TriangleMeshParams", "UP_AXIS_Y", "UP_AXIS_Z", "Vec3",
]
