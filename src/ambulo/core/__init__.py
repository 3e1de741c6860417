"""The one simulation core every app builds on.

- ``physics``: ``PhysicsCfg`` and ``apply_physics``, the only writer of solver options.
- ``scene``: ``new_scene``, ``add_ground``, ``add_light``, ``add_robot`` (through the
  importers), ``compile_scene``: the only scene builder.
- ``entity``: ``Entity``/``EntityData``, the batched view of a robot or body tree.
- ``names``: ``EntityNames``, its model-only name lookup (for code on a bare ``MjModel``).
- ``lifecycle``: ``Component`` (the sensor/randomizer protocol) and ``Simulation``.
- ``rows``: row selectors (indices on the CPU, masks on a GPU) for writes to some worlds.
- ``importers``, ``drives``, ``materials``, ``paths``, ``semantics``: what the builder uses.
"""

from .drives import DriveDefaults, add_drive, ensure_drives, is_drive
from .entity import Entity, EntityData
from .importers import AssetError, load_spec
from .lifecycle import Component, Simulation
from .materials import PhysicsMaterial
from .names import EntityNames
from .paths import PrimNotFoundError, match_names
from .physics import PhysicsCfg, apply_physics
from .scene import (
                    AttachedRobot,
                    GroundCfg,
                    KeyPose,
                    RobotCfg,
                    add_ground,
                    add_light,
                    add_robot,
                    compile_scene,
                    geom_collides,
                    new_scene,
)
from .semantics import semantic_labels, set_semantic_label

__all__ = [
    "AssetError", "AttachedRobot", "Component", "DriveDefaults", "Entity", "EntityData", "EntityNames",
    "GroundCfg", "KeyPose", "PhysicsCfg", "PhysicsMaterial", "PrimNotFoundError", "RobotCfg",
    "Simulation", "add_drive", "add_ground", "add_light", "add_robot", "apply_physics",
    "compile_scene", "ensure_drives", "geom_collides", "is_drive", "load_spec", "match_names", "new_scene",
    "semantic_labels", "set_semantic_label",
]
