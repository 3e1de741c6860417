"""Authored and procedural scenes, each the single home of its furniture, lights and floor.

Content, not an app: a scene module builds into a ``core.scene`` builder (and may read
``robots/`` and ``maps/``), so every app (the replicator, perception, the walking controller, the
ROS 2 bridge, the navigator) places the same rooms. Modules: ``walk_arena``, ``indoor``,
``warehouse``, ``apartment`` (seeded procedural apartments with ground-truth occupancy), ``terrain``
(locomotion terrain tiles as one heightfield, their curriculum and height scan).
"""

from .apartment import apartment
from .indoor import IndoorScene, IndoorSceneCfg, SolidBox, build_indoor_scene
from .warehouse import build_warehouse_scene

__all__ = ["IndoorScene", "IndoorSceneCfg", "SolidBox", "apartment", "build_indoor_scene", "build_warehouse_scene"]
