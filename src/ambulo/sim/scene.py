"""Scene: the registry of named objects on a World's stage, and ground/lights helpers."""

from __future__ import annotations

import difflib
from typing import TYPE_CHECKING, Iterator

import mujoco

if TYPE_CHECKING:
    from .prims import XFormPrim
    from .world import World


class Scene:
    """Objects added to a World by name (Isaac's ``world.scene``)."""

    def __init__(self, world: World):
        self._world = world
        self._objects: dict[str, XFormPrim] = {}

    def add(self, obj):
        """Register a prim or a sensor under ``obj.name``; it is initialized at the next ``world.reset()``.

        Prims (XFormPrim and subclasses) are already on the stage. Sensors
        (``ambulo.sensors``) add their elements now through ``_build(stage)`` and
        are initialized with the engine once the stage is compiled.
        """
        if obj.name in self._objects and self._objects[obj.name] is not obj:
            raise ValueError(
                f"the scene already has an object named {obj.name!r}; pass a unique name="
            )
        self._objects[obj.name] = obj
        if not is_prim(obj):
            obj._build(self._world.stage)  # compiled in at the next reset()
            return obj
        if self._world.engine is not None and self._world.model is not None:
            try:
                obj.initialize(self._world)
            except KeyError:
                pass  # added to the stage after compiling: initialized at the next reset()
        return obj

    def get_object(self, name: str) -> XFormPrim:
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

    def objects(self) -> Iterator[XFormPrim]:
        return iter(list(self._objects.values()))

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
        """A static infinite plane at height ``z_position`` (m) plus a default light.

        Restitution defaults to 0 (Isaac's 0.8 is averaged with bodies' 0 by PhysX;
        MuJoCo combines contacts differently, and a plane that makes every drop
        bounce is rarely what a tutorial wants).
        """
        from .objects import GroundPlane  # noqa: PLC0415 - objects imports prims imports scene

        ground = GroundPlane(
            prim_path=prim_path, name=name, z_position=z_position, color=color,
            physics_material=_material(prim_path, static_friction, dynamic_friction, restitution),
        )
        stage = self._world.stage
        if not any(light.name == "/World/defaultLight" for light in stage.lights):
            add_light(stage, "/World/defaultLight", kind="distant", direction=(0.3, 0.2, -1.0), intensity=0.7)
        if stage.texture("/World/sky") is None:
            stage.add_texture(name="/World/sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                              builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, width=256, height=256,
                              rgb1=[0.55, 0.7, 0.9], rgb2=[0.1, 0.12, 0.18])
        return self.add(ground)


def is_prim(obj) -> bool:
    from .prims import XFormPrim  # noqa: PLC0415

    return isinstance(obj, XFormPrim)


def _material(prim_path, static_friction, dynamic_friction, restitution):
    from .materials import PhysicsMaterial  # noqa: PLC0415

    return PhysicsMaterial(prim_path=prim_path + "/physicsMaterial", static_friction=static_friction,
                           dynamic_friction=dynamic_friction, restitution=restitution)


def add_light(
    stage: mujoco.MjSpec,
    prim_path: str,
    *,
    kind: str = "distant",
    position=(0.0, 0.0, 3.0),
    direction=(0.0, 0.0, -1.0),
    intensity: float = 0.6,
    color=(1.0, 1.0, 1.0),
    cast_shadows: bool = False,
):
    """Add a light: ``kind`` "distant" (sun-like) or "sphere"/"spot" (local).

    ``intensity`` in [0, 1] scales the diffuse colour. Shadows default off: on a
    software rasterizer they cost 10-20x frame rate (see the rendering research).
    """
    if kind not in ("distant", "sphere", "spot"):
        raise ValueError(f"unknown light kind {kind!r}; use 'distant', 'sphere' or 'spot'")
    light = stage.worldbody.add_light(name=prim_path, pos=list(position), dir=list(direction))
    light.type = {
        "distant": mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
        "sphere": mujoco.mjtLightType.mjLIGHT_POINT,
        "spot": mujoco.mjtLightType.mjLIGHT_SPOT,
    }[kind]
    light.diffuse = [intensity * c for c in color]
    light.specular = [0.2 * intensity] * 3
    light.castshadow = cast_shadows
    return light
