"""An apartment's plan (``apartment_layout.Layout``) built into an ``MjSpec`` with the one scene
builder (``ambulo.core.scene``): the floor, one seeded material per look (MuJoCo's builtin
checker, gradient and flat-with-speckles textures in seeded colours; nothing is read from disk),
a floor patch per room, every solid as a static body, a light per room, and optionally the
bundled humanoid at a start pose.

Element names are prim paths: ``/World/apartment/walls/wall_3`` is a body whose one geom is
``/World/apartment/walls/wall_3/geom``.
"""

from __future__ import annotations

import colorsys
import math

import mujoco
import numpy as np

from ..core import GroundCfg, RobotCfg, add_ground, add_light, add_robot, new_scene
from ..robots import humanoid
from .apartment_layout import Layout

LOOKS = ("wall", "furniture", "wood", "fabric", "metal", "plant", "rug", "floor_tiles", "floor_wood")
"""Material families; each apartment draws its colours and textures for these from its seed."""
LOOKS_PRIM = "/World/Looks/apartment"
GROUND_PRIM = "/World/apartment/floor"


def _colour(rng: np.random.Generator, hue_range=(0.0, 1.0), sat_range=(0.1, 0.5), val_range=(0.4, 0.9)):
    hue, sat, val = (float(rng.uniform(*r)) for r in (hue_range, sat_range, val_range))
    return list(colorsys.hsv_to_rgb(hue % 1.0, sat, val))


def _add_looks(spec: mujoco.MjSpec, rng: np.random.Generator, texture_px: int) -> dict[str, str]:
    """One material per look (name -> material name), textures in seeded colours."""
    cube, two_d = mujoco.mjtTexture.mjTEXTURE_CUBE, mujoco.mjtTexture.mjTEXTURE_2D
    builtin, mark = mujoco.mjtBuiltin, mujoco.mjtMark
    recipes = {  # look: (texture type, builtin, mark, hue range, saturation range, texrepeat per metre)
        "wall": (cube, builtin.mjBUILTIN_FLAT, mark.mjMARK_RANDOM, (0.0, 1.0), (0.02, 0.25), 1.0),
        "furniture": (cube, builtin.mjBUILTIN_GRADIENT, mark.mjMARK_NONE, (0.0, 1.0), (0.2, 0.7), 1.0),
        "wood": (cube, builtin.mjBUILTIN_FLAT, mark.mjMARK_RANDOM, (0.05, 0.12), (0.35, 0.7), 1.0),
        "fabric": (cube, builtin.mjBUILTIN_CHECKER, mark.mjMARK_NONE, (0.0, 1.0), (0.2, 0.6), 8.0),
        "metal": (cube, builtin.mjBUILTIN_GRADIENT, mark.mjMARK_NONE, (0.55, 0.65), (0.0, 0.15), 1.0),
        "plant": (cube, builtin.mjBUILTIN_FLAT, mark.mjMARK_RANDOM, (0.22, 0.4), (0.4, 0.8), 1.0),
        "rug": (two_d, builtin.mjBUILTIN_CHECKER, mark.mjMARK_EDGE, (0.0, 1.0), (0.3, 0.8), 3.0),
        "floor_tiles": (two_d, builtin.mjBUILTIN_CHECKER, mark.mjMARK_EDGE, (0.0, 1.0), (0.0, 0.3), 2.0),
        "floor_wood": (two_d, builtin.mjBUILTIN_FLAT, mark.mjMARK_RANDOM, (0.05, 0.1), (0.3, 0.6), 1.0),
    }
    names = {}
    for look in LOOKS:
        kind, texture, marks, hue, sat, repeat = recipes[look]
        rgb1 = _colour(rng, hue, sat)
        rgb2 = [min(1.0, c * float(rng.uniform(0.6, 0.9))) for c in rgb1]
        name = f"{LOOKS_PRIM}/{look}"
        spec.add_texture(name=name + "/tex", type=kind, builtin=texture, mark=marks, rgb1=rgb1, rgb2=rgb2,
                         markrgb=_colour(rng, hue, sat, (0.2, 0.95)), random=0.02,
                         width=texture_px, height=texture_px)
        material = spec.add_material(name=name, texuniform=True, texrepeat=[repeat, repeat],
                                     specular=float(rng.uniform(0.05, 0.4)), shininess=float(rng.uniform(0.1, 0.6)))
        material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = name + "/tex"
        names[look] = name
    return names


def build_spec(layout: Layout, rng: np.random.Generator, *, texture_px: int, spec: mujoco.MjSpec | None = None,
               robot_pose: tuple[float, float, float] | None = None) -> mujoco.MjSpec:
    """``layout`` as static bodies in ``spec`` (a new scene if None), lit and textured from ``rng``;
    with the humanoid at ``robot_pose`` (x m, y m, yaw rad; its soles on the floor) unless None."""
    spec = new_scene("ambulo_apartment") if spec is None else spec
    spec.visual.headlight.active = 0
    x0, y0, x1, y1 = layout.extent_xy_m
    centre = ((x0 + x1) / 2, (y0 + y1) / 2)
    size = max(x1 - x0, y1 - y0) + 4.0
    ground = add_ground(spec, GroundCfg(prim_path=GROUND_PRIM, size_m=size, render_grid_m=1.0, sky=False,
                                        sun=False, color=tuple(_colour(rng, sat_range=(0.0, 0.2)))))
    spec.body(GROUND_PRIM).pos = [centre[0], centre[1], 0.0]
    looks = _add_looks(spec, rng, texture_px)
    ground.material = looks["floor_tiles"]
    for room in layout.rooms:  # a floor patch per room, 2 mm thin, seen but never touched
        half = [(room.max_xy_m[0] - room.min_xy_m[0]) / 2, (room.max_xy_m[1] - room.min_xy_m[1]) / 2, 0.001]
        body = spec.worldbody.add_body(name=f"/World/apartment/{room.name}/floor",
                                       pos=[room.min_xy_m[0] + half[0], room.min_xy_m[1] + half[1], 0.001])
        look = "floor_wood" if rng.random() < 0.5 else "floor_tiles"
        body.add_geom(name=f"/World/apartment/{room.name}/floor/geom", type=mujoco.mjtGeom.mjGEOM_BOX, size=half,
                      material=looks[look], contype=0, conaffinity=0)
    for solid in layout.solids:
        quat = [math.cos(solid.yaw_rad / 2), 0.0, 0.0, math.sin(solid.yaw_rad / 2)]
        body = spec.worldbody.add_body(name=solid.name, pos=list(solid.center_m), quat=quat)
        if solid.shape == "box":
            kind, size3 = mujoco.mjtGeom.mjGEOM_BOX, list(solid.half_m)
        else:
            kind, size3 = mujoco.mjtGeom.mjGEOM_CYLINDER, [solid.half_m[0], solid.half_m[2], 0.0]
        geom = body.add_geom(name=solid.name + "/geom", type=kind, size=size3, material=looks[solid.look])
        if not solid.collides:
            geom.contype = geom.conaffinity = 0
    add_light(spec, "/World/apartment/sun", kind="distant", direction=(float(rng.uniform(-0.5, 0.5)),
                                                                          float(rng.uniform(-0.5, 0.5)), -1.0),
              intensity=float(rng.uniform(0.25, 0.45)), ambient=float(rng.uniform(0.2, 0.35)))
    warm = _colour(rng, (0.05, 0.15), (0.0, 0.3), (0.9, 1.0))
    for k, (lx, ly, lz) in enumerate(layout.lights_xyz_m):
        light = add_light(spec, f"/World/apartment/lights/lamp_{k}", kind="sphere", position=(lx, ly, lz),
                          intensity=float(rng.uniform(0.15, 0.35)), color=tuple(warm))
        light.attenuation = [1.0, 0.0, float(rng.uniform(0.05, 0.2))]
    if robot_pose is not None:
        x, y, yaw = (float(v) for v in robot_pose)
        add_robot(spec, RobotCfg(file=humanoid.ASSET, prim_path=humanoid.PRIM_PATH, pos_m=(x, y, 0.0),
                                 quat=(math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))))
    return spec


__all__ = ["GROUND_PRIM", "LOOKS", "LOOKS_PRIM", "build_spec"]
