"""Which ambulo object answers each Isaac Sim module name: the table ``ambulo run`` imports from.

``MODULES`` maps an Isaac module (``isaacsim.core.api.objects``) to the names it provides,
each the ``"ambulo.module:attribute"`` that answers it. Isaac Sim 4.5+ names (``isaacsim.*``)
and the older ``omni.isaac.*`` ones point at the same objects, except where Isaac itself
changed meaning (``omni.isaac.core.prims.XFormPrim`` is one prim; ``isaacsim.core.prims.
XFormPrim`` is a view over many). ``HINTS`` says what to use for Isaac names ambulo lacks.
"""

from __future__ import annotations

import importlib

from .gym.names import HINTS as GYM_HINTS
from .gym.names import MODULES as GYM_MODULES
from .gym.names import ROOTS as GYM_ROOTS
from .replicator_names import MODULES as REPLICATOR_MODULES


def _from(module: str, *names: str, **renamed: str) -> dict[str, str]:
    """``{isaac_name: "module:ambulo_name"}``: ``names`` are the same in both, ``renamed`` maps
    Isaac's name to ambulo's."""
    table = {name: f"{module}:{name}" for name in names}
    table.update({isaac: f"{module}:{ours}" for isaac, ours in renamed.items()})
    return table


def _all_of(module: str) -> dict[str, str]:
    """Every public name (``__all__``) of an ambulo module written to Isaac's signatures."""
    return _from(module, *importlib.import_module(module).__all__)


_SIM = "ambulo.sim"
_SHAPES = tuple(f"{kind}{shape}" for kind in ("Dynamic", "Fixed", "Visual")
                for shape in ("Cuboid", "Sphere", "Cylinder", "Capsule"))

_APP = _from("ambulo.isaac.app", "SimulationApp")
_WORLD = {**_from(_SIM, "World", SimulationContext="World"),
          **_from("ambulo.isaac.physics_context", "PhysicsContext")}
_OBJECTS = _from(_SIM, *_SHAPES, "GroundPlane")
_ROBOTS = _from(_SIM, "Robot")
_SCENES = _from(_SIM, "Scene")
_CONTROLLERS = {**_from(_SIM, "ArticulationController"), **_from("ambulo.isaac.controllers", "BaseController")}
_MATERIALS = _from(_SIM, "PhysicsMaterial")
_STAGE = _all_of("ambulo.isaac.stage_utils")
_PRIMS = _all_of("ambulo.isaac.prim_utils")
_TYPES = {**_from(_SIM, "ArticulationAction"), **_from("ambulo.sim.actions", "ArticulationActions"),
          **_all_of("ambulo.sim.states")}
_VIEWS = "ambulo.sim.views"
_NUCLEUS = _from(_SIM, "get_assets_root_path")
_VIEWPORTS = {**_from(_SIM, "set_camera_view"), **_from("ambulo.sim.viewport", "get_intrinsics_matrix")}
_TASKS = _from("ambulo.sim.tasks", "BaseTask")
_SEMANTICS = _from("ambulo.isaac.semantics", "add_update_semantics", "add_labels")
_PHYSICS_CONTEXT = _from("ambulo.isaac.physics_context", "PhysicsContext")
_ROTATIONS = _from("ambulo.isaac.rotations", "euler_angles_to_quat", "quat_to_euler_angles",
                   "quat_to_rot_matrix", "rot_matrix_to_quat")
_WHEELED = _from(_SIM, "WheeledRobot")
_DIFFERENTIAL = _from(_SIM, "DifferentialController")
_SAMPLE = _from("ambulo.isaac.sample", "BaseSample")
_KIT_COMMANDS = "ambulo.isaac.kit_commands"
"""Named, not imported, here: it imports the hook, which imports this table."""
_URDF = {**_from("ambulo.isaac.urdf_types", "ImportConfig", "UrdfJoint", "UrdfJointDrive", "UrdfJointDriveType",
                 "UrdfJointDynamics", "UrdfJointLimit", "UrdfJointTargetType", "UrdfJointType", "UrdfLink",
                 "UrdfNormalSubdivisionScheme", "UrdfRobot"),
         **_from("ambulo.isaac.urdf_importer", "Urdf", "acquire_urdf_interface", "release_urdf_interface")}
_URDF_COMMANDS = _from("ambulo.isaac.urdf_importer", "URDFCreateImportConfig", "URDFImportRobot",
                       "URDFParseAndImportFile", "URDFParseFile", "URDFParseText")
_CARB = _from("ambulo.isaac.carb", "settings", "log_info", "log_warn", "log_error", "log_verbose",
              "Float3", "Float4")

MODULES: dict[str, dict[str, str]] = {
    # the app
    "isaacsim": _APP,
    "isaacsim.simulation_app": _APP,
    "omni.isaac.kit": _APP,
    # the core API (Isaac Sim 4.5+)
    "isaacsim.core.api": _WORLD,
    "isaacsim.core.api.world": _WORLD,
    "isaacsim.core.api.simulation_context": _from(_SIM, SimulationContext="World"),
    "isaacsim.core.api.objects": _OBJECTS,
    **{f"isaacsim.core.api.objects.{shape.lower()}": {k: v for k, v in _OBJECTS.items() if k.endswith(shape)}
       for shape in ("Cuboid", "Sphere", "Cylinder", "Capsule")},
    "isaacsim.core.api.objects.ground_plane": _from(_SIM, "GroundPlane"),
    "isaacsim.core.api.physics_context": _PHYSICS_CONTEXT,
    "isaacsim.core.api.robots": _ROBOTS,
    "isaacsim.core.api.scenes": _SCENES,
    "isaacsim.core.api.tasks": _TASKS,
    "isaacsim.core.api.tasks.base_task": _TASKS,
    "isaacsim.core.api.controllers": _CONTROLLERS,
    "isaacsim.core.api.controllers.articulation_controller": _from(_SIM, "ArticulationController"),
    "isaacsim.core.api.materials": _MATERIALS,
    "isaacsim.core.prims": {**_from(_SIM, SingleArticulation="Articulation", SingleXFormPrim="XFormPrim",
                                    SingleRigidPrim="RigidPrim"),
                            **_from(_VIEWS, Articulation="ArticulationView", XFormPrim="XFormPrimView",
                                    RigidPrim="RigidPrimView")},
    "isaacsim.core.utils.stage": _STAGE,
    "isaacsim.core.utils.prims": _PRIMS,
    "isaacsim.core.utils.types": _TYPES,
    "isaacsim.core.utils.nucleus": _NUCLEUS,
    "isaacsim.storage.native": _NUCLEUS,
    "isaacsim.core.utils.viewports": _VIEWPORTS,
    "isaacsim.core.utils.semantics": _SEMANTICS,
    "isaacsim.core.utils.rotations": _ROTATIONS,
    "isaacsim.robot.wheeled_robots.robots": _WHEELED,
    "isaacsim.robot.wheeled_robots.controllers": _DIFFERENTIAL,
    "isaacsim.robot.wheeled_robots.controllers.differential_controller": _DIFFERENTIAL,
    "isaacsim.examples.interactive.base_sample": _SAMPLE,
    # the same objects under the names of Isaac Sim 2023.1-4.2
    "omni.isaac.core": _WORLD,
    "omni.isaac.core.world": _WORLD,
    "omni.isaac.core.simulation_context": _from(_SIM, SimulationContext="World"),
    "omni.isaac.core.objects": _OBJECTS,
    "omni.isaac.core.robots": _ROBOTS,
    "omni.isaac.core.scenes": _SCENES,
    "omni.isaac.core.tasks": _TASKS,
    "omni.isaac.core.tasks.base_task": _TASKS,
    "omni.isaac.core.controllers": _CONTROLLERS,
    "omni.isaac.core.materials": _MATERIALS,
    "omni.isaac.core.articulations": {**_from(_SIM, "Articulation"), **_from(_VIEWS, "ArticulationView")},
    "omni.isaac.core.prims": {**_from(_SIM, "XFormPrim", "RigidPrim"), **_from(_VIEWS, "XFormPrimView", "RigidPrimView")},
    "omni.isaac.core.utils.stage": _STAGE,
    "omni.isaac.core.utils.prims": _PRIMS,
    "omni.isaac.core.physics_context": _PHYSICS_CONTEXT,
    **{f"omni.isaac.core.objects.{shape.lower()}": {k: v for k, v in _OBJECTS.items() if k.endswith(shape)}
       for shape in ("Cuboid", "Sphere", "Cylinder", "Capsule")},
    "omni.isaac.core.objects.ground_plane": _from(_SIM, "GroundPlane"),
    "omni.isaac.core.utils.types": _TYPES,
    "omni.isaac.core.utils.nucleus": _NUCLEUS,
    "omni.isaac.core.utils.viewports": _VIEWPORTS,
    "omni.isaac.core.utils.semantics": _SEMANTICS,
    "omni.isaac.core.utils.rotations": _ROTATIONS,
    "omni.isaac.wheeled_robots.robots": _WHEELED,
    "omni.isaac.wheeled_robots.controllers": _DIFFERENTIAL,
    "omni.isaac.wheeled_robots.controllers.differential_controller": _DIFFERENTIAL,
    "omni.isaac.examples.base_sample": _SAMPLE,
    # sensors
    "isaacsim.sensors.camera": _from("ambulo.sim.camera", "Camera"),
    "isaacsim.sensors.physics": {**_from("ambulo.sim.imu_sensor", "IMUSensor"),
                                 **_from("ambulo.sim.contact_sensor", "ContactSensor")},
    "omni.isaac.sensor": {**_from("ambulo.sim.camera", "Camera"), **_from("ambulo.sim.imu_sensor", "IMUSensor"),
                          **_from("ambulo.sim.contact_sensor", "ContactSensor")},
    # Kit: settings and logging, the USD context, the app, PhysX's authoring helpers
    "carb": _CARB,
    "omni.usd": _all_of("ambulo.isaac.omni_usd"),
    "omni.kit.app": _all_of("ambulo.isaac.kit_app"),
    "omni.physx.scripts.physicsUtils": _all_of("ambulo.isaac.physics_utils"),
    # Kit commands (omni.kit.commands.execute("CreatePrim", ...)) and their undo stack
    "omni.kit.commands": _from(_KIT_COMMANDS, "Command", "create", "execute", "get_command_class", "get_command_doc",
                               "get_command_parameters", "get_commands", "get_commands_list", "register",
                               "register_all_commands_in_module", "set_logging_enabled", "unregister",
                               "unregister_module_commands"),
    "omni.kit.undo": _from(_KIT_COMMANDS, "can_redo", "can_undo", "clear_history", "clear_stack", "get_redo_stack",
                           "get_undo_stack", "group", "redo", "undo"),
    # the URDF importer: Isaac Sim 4.x, 2023.1 and 2022 names
    "isaacsim.asset.importer.urdf": _URDF_COMMANDS,
    "isaacsim.asset.importer.urdf._urdf": _URDF,
    "omni.importer.urdf": _URDF_COMMANDS,
    "omni.importer.urdf._urdf": _URDF,
    "omni.isaac.urdf": _URDF_COMMANDS,
    "omni.isaac.urdf._urdf": _URDF,
}
"""Isaac module name -> {name it provides: "ambulo.module:attribute"}."""
MODULES.update(REPLICATOR_MODULES)
MODULES.update(GYM_MODULES)  # Isaac Gym's isaacgym.* (ambulo.isaac.gym)

INJECTED: dict[str, str] = {"pxr.PhysxSchema": "ambulo.isaac.physx_schema"}
"""Modules Isaac Sim adds to other packages (usd-core's ``pxr`` has no PhysxSchema) -> the ambulo
module whose ``as_module(name)`` answers them during a run (and ``restore()`` cleans up after)."""

ROOTS = ("isaacsim", "omni", "carb", *GYM_ROOTS)
"""Top-level names the hook answers for: every module under them is Isaac's, found or not."""

HINTS: dict[str, str] = {
    "DynamicCone": "not supported: ambulo has cuboids, spheres, cylinders and capsules",
    "FixedCone": "not supported: ambulo has cuboids, spheres, cylinders and capsules",
    "VisualCone": "not supported: ambulo has cuboids, spheres, cylinders and capsules",
    "PreviewSurface": "not supported: give shapes a color= (RGB) instead",
    "OmniPBR": "not supported: give shapes a color= (RGB) instead",
}
HINTS.update(GYM_HINTS)
"""What to use instead of an Isaac name that ambulo does not provide."""


def is_package(module: str) -> bool:
    """Whether some table module lives under ``module`` (so it needs a ``__path__``)."""
    prefix = module + "."
    return module in ROOTS or any(name.startswith(prefix) for name in MODULES)


def is_known(module: str) -> bool:
    """Whether ``module`` is in the table or a package on the way to one."""
    return module in MODULES or is_package(module)


def submodules(module: str) -> list[str]:
    """The names of the table's modules (or packages on the way to them) directly under ``module``."""
    prefix = module + "."
    return sorted({name[len(prefix):].split(".")[0] for name in MODULES if name.startswith(prefix)})


__all__ = ["HINTS", "INJECTED", "MODULES", "ROOTS", "is_known", "is_package", "submodules"]
