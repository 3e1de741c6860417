"""Primitive objects (Isaac's DynamicCuboid, FixedSphere, VisualCapsule, ...) and the ground plane.

Each constructor adds a body with one geom to the World's stage at ``prim_path``.
Dynamic objects get a free joint; fixed ones hang from the world; visual ones
have no collision. Sizes: cuboid edge ``size * scale``, sphere ``radius``,
cylinder/capsule ``radius`` and ``height`` (cylinder: full height; capsule: of the
straight part), all along local z. Positions, sizes and linear velocities are in stage
units (``World.stage_units_in_meters``: a 50-unit cube in a cm World is 0.5 m); ``scale``
is unitless, ``mass`` kg, ``density`` kg/m^3.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..core import GroundCfg, PhysicsMaterial, add_ground, set_semantic_label
from ..utils.checks import InvalidValueError, check_positive, check_quat, check_vector
from .current import current_world
from .prims import RigidPrim, XFormPrim

_G = mujoco.mjtGeom


def _current_stage() -> mujoco.MjSpec:
    return current_world("adding objects to the stage").stage


class _Primitive(RigidPrim):
    _geom_type: int = _G.mjGEOM_BOX
    _dynamic = True
    _collision = True

    def __init__(
        self,
        prim_path: str,
        name: str | None = None,
        position=None,
        orientation=None,
        scale=None,
        color=None,
        mass: float | None = None,
        density: float | None = None,
        physics_material: PhysicsMaterial | None = None,
        semantic_label: str | None = None,
        visible: bool = True,
        translation=None,
        linear_velocity=None,
        angular_velocity=None,
        **size_kwargs,
    ):
        world = current_world("adding objects to the stage")
        stage, units = world.stage, world.stage_units_in_meters
        if stage.body(prim_path) is not None:
            raise ValueError(f"a prim already exists at {prim_path!r}; choose another prim_path")
        if mass is not None:
            check_positive("mass", mass, "pass kg > 0, e.g. mass=1.0")
        if density is not None:
            check_positive("density", density, "pass kg/m^3 > 0, e.g. density=1000")
        if not self._dynamic and (linear_velocity is not None or angular_velocity is not None):
            raise ValueError(f"{type(self).__name__} does not move: give velocities to a Dynamic* object")
        for what, value in (("position", position), ("translation", translation)):
            if value is not None:  # checked before the stage changes
                check_vector(what, value, 3, "pass (x, y, z) in m (in stage units if the World sets stage_units_in_meters), finite")
        if orientation is not None:
            check_quat("orientation", orientation)
        scale = np.ones(3) if scale is None else np.broadcast_to(
            check_vector("scale", np.broadcast_to(np.asarray(scale, float), (3,)), 3, "pass 3 positive factors"), (3,))
        if (scale <= 0).any():
            raise InvalidValueError("scale", list(scale), "every factor must be > 0", "pass e.g. scale=(1, 1, 1)")
        for key, value in size_kwargs.items():
            check_positive(key, value, f"pass {key} > 0 in stage units")
        if color is not None:
            color = check_vector("color", np.asarray(color, float)[:3] if np.size(color) >= 3 else color, 3,
                                 "pass (r, g, b) in 0..1")
        body = stage.worldbody.add_body(name=prim_path)
        if self._dynamic:
            body.add_freejoint(name=prim_path + "/root_joint")
        # sizes are in stage units: scaling them by metres per unit is one more factor of scale
        geom = body.add_geom(name=prim_path + "/geom", type=self._geom_type,
                             size=self._geom_size(scale * units, **size_kwargs))
        rgba = [0.5, 0.5, 0.5, 1.0] if color is None else [*map(float, color[:3]), 1.0]
        geom.rgba = rgba if visible else [rgba[0], rgba[1], rgba[2], 0.0]
        if mass is not None:
            geom.mass = float(mass)
        elif density is not None:
            geom.density = float(density)
        if not self._collision:
            geom.contype = geom.conaffinity = 0
            geom.mass = 0.0 if not self._dynamic else geom.mass
        if physics_material is not None:
            physics_material.apply_to(geom)
        if semantic_label is not None:
            set_semantic_label(stage, prim_path, semantic_label)
        self.color = rgba[:3]
        super().__init__(prim_path, name, position=position, orientation=orientation, translation=translation,
                         linear_velocity=linear_velocity, angular_velocity=angular_velocity)

    def _geom_size(self, scale: np.ndarray, **sizes) -> list[float]:
        """MuJoCo geom size (half extents / radius, half length), m: ``sizes`` times ``scale``
        (metres per stage unit included)."""
        raise NotImplementedError(f"{type(self).__name__} defines no shape")


class _Cuboid(_Primitive):
    _geom_type = _G.mjGEOM_BOX

    def _geom_size(self, scale, size: float = 1.0):
        return list(0.5 * size * scale)


class _Sphere(_Primitive):
    _geom_type = _G.mjGEOM_SPHERE

    def _geom_size(self, scale, radius: float = 0.5):
        return [radius * float(scale.max()), 0.0, 0.0]


class _Cylinder(_Primitive):
    _geom_type = _G.mjGEOM_CYLINDER

    def _geom_size(self, scale, radius: float = 0.5, height: float = 1.0):
        return [radius * float(max(scale[0], scale[1])), 0.5 * height * float(scale[2]), 0.0]


class _Capsule(_Cylinder):
    _geom_type = _G.mjGEOM_CAPSULE


def _variants(base, doc):
    dynamic = type(f"Dynamic{base.__name__[1:]}", (base,), {"__doc__": f"A dynamic {doc} (free joint)."})
    fixed = type(f"Fixed{base.__name__[1:]}", (base,), {"_dynamic": False, "__doc__": f"A static {doc}."})
    visual = type(f"Visual{base.__name__[1:]}", (base,),
                  {"_dynamic": False, "_collision": False, "__doc__": f"A {doc} without collision."})
    for cls in (dynamic, fixed, visual):
        cls.__module__ = __name__
    return dynamic, fixed, visual


DynamicCuboid, FixedCuboid, VisualCuboid = _variants(_Cuboid, "box")
DynamicSphere, FixedSphere, VisualSphere = _variants(_Sphere, "sphere")
DynamicCylinder, FixedCylinder, VisualCylinder = _variants(_Cylinder, "cylinder")
DynamicCapsule, FixedCapsule, VisualCapsule = _variants(_Capsule, "capsule")


class GroundPlane(XFormPrim):
    """A static infinite plane (rendered ``size_m`` square) at height ``z_position`` (stage
    units), built by ``ambulo.core.add_ground`` (the ground every app uses); ``cfg`` (metres)
    overrides the arguments."""

    def __init__(self, prim_path: str = "/World/groundPlane", name: str | None = None,
                 z_position: float = 0.0, color=(0.35, 0.4, 0.45),
                 physics_material: PhysicsMaterial | None = None, size_m: float = 100.0,
                 cfg: GroundCfg | None = None):
        if cfg is None:
            material = physics_material or PhysicsMaterial()
            units = current_world("adding a ground plane").stage_units_in_meters
            cfg = GroundCfg(prim_path=prim_path, z_m=z_position * units, color=tuple(color), size_m=size_m,
                            static_friction=material.static_friction,
                            dynamic_friction=material.dynamic_friction,
                            restitution=material.restitution, sky=False, sun=False)
        add_ground(_current_stage(), cfg)
        super().__init__(cfg.prim_path, name)
