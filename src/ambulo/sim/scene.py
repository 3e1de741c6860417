"""Scene: the registry of named objects on a World's stage (Isaac's ``world.scene``)."""

from __future__ import annotations

import difflib
from collections.abc import Iterator
from typing import TYPE_CHECKING

from ..core import GroundCfg
from ..core.paths import resolve_spec_prim
from .objects import GroundPlane
from .prims import XFormPrim

if TYPE_CHECKING:
    from .world import World


class Scene:
    """Objects added to a World by name: prims (already on the stage) and components (sensors)."""

    def __init__(self, world: World):
        self._world = world
        self._objects: dict = {}

    def add(self, obj):
        """Register a prim or a sensor under ``obj.name``; it is initialized at the next ``world.reset()``.

        Prims (XFormPrim and subclasses) are already on the stage. Components (sensors of
        ``ambulo.sensors``) are handed to the core lifecycle, which builds them into the stage
        now and initializes them with the engine once the stage is compiled.
        """
        if obj.name in self._objects and self._objects[obj.name] is not obj:
            raise ValueError(
                f"the scene already has an object named {obj.name!r}; pass a unique name="
            )
        if not is_prim(obj):
            self._world.sim.add(obj)  # compiled in at the next reset()
            self._objects[obj.name] = obj
            return obj
        if self._world.engine is not None and self._world.model is not None:
            try:
                obj.initialize(self._world)
            except KeyError:
                # on the stage since the last compile: initialized at the next reset(); nowhere
                # on the stage: a wrong path, said now (with did-you-mean) rather than at reset
                if not _on_stage(self._world.stage, obj.prim_path):
                    raise
        self._objects[obj.name] = obj
        return obj

    def get_object(self, name: str):
        if name not in self._objects:
            close = difflib.get_close_matches(name, list(self._objects), n=3)
            hint = f" Did you mean {', '.join(map(repr, close))}?" if close else ""
            raise KeyError(f"no object named {name!r} in the scene.{hint} Have: {sorted(self._objects)}")
        return self._objects[name]

    def object_exists(self, name: str) -> bool:
        return name in self._objects

    def remove_object(self, name: str) -> None:
        self.get_object(name)
        del self._objects[name]

    def objects(self) -> Iterator:
        return iter(list(self._objects.values()))

    def prims(self) -> Iterator[XFormPrim]:
        """The registered prims (not sensors), in the order they were added."""
        return iter([obj for obj in self._objects.values() if is_prim(obj)])

    def add_default_ground_plane(
        self,
        z_position: float = 0.0,
        name: str = "default_ground_plane",
        prim_path: str = "/World/defaultGroundPlane",
        static_friction: float = 0.5,
        dynamic_friction: float = 0.5,
        restitution: float = 0.0,
        color=(0.35, 0.4, 0.45),
    ) -> XFormPrim:
        """A static infinite plane at height ``z_position`` (stage units), a sky and a default light.

        Friction is Isaac's 0.5. Restitution stays 0, not Isaac's 0.8, on purpose: PhysX averages
        it with the body's 0 and applies it only above a 0.2 m/s bounce threshold, so resting
        bodies stay still. MuJoCo has no threshold and realises restitution as an underdamped
        contact spring. With the combined 0.4, a 2 kg box dropped on the plane still rocked at
        1.3 cm/s after 10 s, so pass ``restitution=`` only for scenes that need bounces.
        """
        units = self._world.stage_units_in_meters
        cfg = GroundCfg(prim_path=prim_path, z_m=z_position * units, static_friction=static_friction,
                        dynamic_friction=dynamic_friction, restitution=restitution, color=tuple(color))
        return self.add(GroundPlane(cfg=cfg, name=name))


def _on_stage(stage, prim_path: str) -> bool:
    """Whether ``prim_path`` names a body or a referenced file's frame of the (uncompiled) stage."""
    try:
        resolve_spec_prim(stage, prim_path)
    except KeyError:
        return False
    return True


def is_prim(obj) -> bool:
    return isinstance(obj, XFormPrim)
