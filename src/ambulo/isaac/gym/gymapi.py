"""``isaacgym.gymapi`` under ``ambulo run``: the value types, the enums and ``acquire_gym``."""

from .gym import (
                  DOMAIN_ACTOR,
                  DOMAIN_ENV,
                  DOMAIN_SIM,
                  ENV_SPACE,
                  GLOBAL_SPACE,
                  LOCAL_SPACE,
                  STATE_ALL,
                  STATE_NONE,
                  STATE_POS,
                  STATE_VEL,
                  acquire_gym,
)
from .types import (
                  DOF_INVALID,
                  DOF_MODE_EFFORT,
                  DOF_MODE_NONE,
                  DOF_MODE_POS,
                  DOF_MODE_VEL,
                  DOF_ROTATION,
                  DOF_TRANSLATION,
                  SIM_FLEX,
                  SIM_PHYSX,
                  UP_AXIS_Y,
                  UP_AXIS_Z,
                  AssetOptions,
                  CameraProperties,
                  FlexParams,
                  HeightFieldParams,
                  PhysXParams,
                  PlaneParams,
                  Quat,
                  RigidBodyProperties,
                  RigidShapeProperties,
                  SimParams,
                  Transform,
                  TriangleMeshParams,
                  Vec3,
)

KEY_ESCAPE, KEY_V, KEY_R, KEY_SPACE = 27, 86, 82, 32
"""Keyboard keys scripts subscribe the (headless) viewer to."""
IMAGE_COLOR, IMAGE_DEPTH, IMAGE_SEGMENTATION = 0, 1, 2
"""Camera image kinds (camera sensors: ambulo.sensors' Camera)."""

__all__ = [
    "AssetOptions", "CameraProperties", "DOF_INVALID", "DOF_MODE_EFFORT", "DOF_MODE_NONE", "DOF_MODE_POS",
    "DOF_MODE_VEL", "DOF_ROTATION", "DOF_TRANSLATION", "DOMAIN_ACTOR", "DOMAIN_ENV", "DOMAIN_SIM", "ENV_SPACE",
    "FlexParams", "GLOBAL_SPACE", "HeightFieldParams", "IMAGE_COLOR", "IMAGE_DEPTH", "IMAGE_SEGMENTATION", "KEY_ESCAPE", "KEY_R",
    "KEY_SPACE", "KEY_V", "LOCAL_SPACE", "PhysXParams", "PlaneParams", "Quat", "RigidBodyProperties",
    "RigidShapeProperties", "SIM_FLEX", "SIM_PHYSX", "STATE_ALL", "STATE_NONE", "STATE_POS", "STATE_VEL",
    "SimParams", "Transform", "TriangleMeshParams", "UP_AXIS_Y", "UP_AXIS_Z", "Vec3", "acquire_gym",
]
