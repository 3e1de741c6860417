"""The Isaac-Sim-style scene and robot API on MuJoCo.

A tutorial written for Isaac Sim ports by changing its imports to ``ambulo.sim``.
"""

from ..assets import get_assets_root_path
from ..core import (
    AssetError,
    DriveDefaults,
    PhysicsCfg,
    PhysicsMaterial,
    PrimNotFoundError,
    add_light,
    semantic_labels,
    set_semantic_label,
)
from .actions import ArticulationAction
from .articulation import Articulation, Robot
from .controller import ArticulationController
from .objects import (
    DynamicCapsule,
    DynamicCuboid,
    DynamicCylinder,
    DynamicSphere,
    FixedCapsule,
    FixedCuboid,
    FixedCylinder,
    FixedSphere,
    GroundPlane,
    VisualCapsule,
    VisualCuboid,
    VisualCylinder,
    VisualSphere,
)
from .prims import RigidPrim, XFormPrim
from .scene import Scene
from .stage import add_reference_to_stage, get_current_stage
from .viewport import set_camera_view
from .walking import HumanoidWalkingPolicy
from .wheeled import DifferentialController, WheeledRobot
from .world import World


def add_update_semantics(prim_path: str, semantic_label: str) -> None:
    """Label the prim at ``prim_path`` with class ``semantic_label`` (Isaac's helper)."""
    set_semantic_label(get_current_stage(), prim_path, semantic_label)


__all__ = [
    "World", "PhysicsCfg", "Scene", "Robot", "Articulation", "ArticulationAction",
    "ArticulationController", "WheeledRobot", "DifferentialController", "XFormPrim", "RigidPrim",
    "add_reference_to_stage", "get_current_stage", "get_assets_root_path", "set_camera_view",
    "PhysicsMaterial", "DriveDefaults", "GroundPlane", "add_light", "add_update_semantics",
    "set_semantic_label", "semantic_labels", "AssetError", "PrimNotFoundError",
    "DynamicCuboid", "FixedCuboid", "VisualCuboid", "DynamicSphere", "FixedSphere", "VisualSphere",
    "DynamicCylinder", "FixedCylinder", "VisualCylinder", "DynamicCapsule", "FixedCapsule",
    "VisualCapsule", "HumanoidWalkingPolicy",
]
