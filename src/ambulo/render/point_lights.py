"""Point lights for MuJoCo 4.0's OpenGL rasterizer, which leaves them dark.

``mjv_makeLights`` (inside ``mjv_updateScene``) copies a light's attenuation, cutoff and exponent
into the ``MjvScene`` for spot lights only; a point light (``mjLIGHT_POINT``, what
``core.scene.add_light(kind="sphere")`` makes) reaches ``mjr_render`` with attenuation (0, 0, 0)
and cutoff 0, so the classic renderer draws it as nothing (or, with the 1/0 attenuation, a
meaningless flat shade). The lamps of ``scenes/indoor.py`` and ``scenes/warehouse.py`` never lit a
GL frame.

``light_point_lights`` rewrites each point light of a filled scene, after ``mjv_updateScene`` and
before ``mjr_render``, as the light the rasterizer does draw the same way: a spot with cutoff 180
deg (the whole sphere: OpenGL's "not a spot" value, so the direction no longer matters) and
exponent 0 (no fall-off toward the cone's edge), with the model's attenuation (constant, linear,
quadratic in the distance, m). A plane under it is then lit ``diffuse * cos(incidence) /
(a0 + a1 d + a2 d^2)``, brightest under the light. Shadows of such a light come from the
rasterizer's spot shadow map, a cone around the light's ``dir``: a box under a lamp pointing down
casts its shadow, one pointing up or sideways casts none (our scenes' lamps cast none anyway: ``add_light`` defaults
``castshadow`` off).

Only the rasterizer's scene is changed: the PBR and path tiers read lights from the model and their
own ``MjvScene`` (``render.scene_description``) and map point lights themselves.
"""

from __future__ import annotations

import mujoco
import numpy as np

_POINT = int(mujoco.mjtLightType.mjLIGHT_POINT)
_SPOT = int(mujoco.mjtLightType.mjLIGHT_SPOT)

WHOLE_SPHERE_CUTOFF_DEG = 180.0
"""OpenGL's spot cutoff that means "all directions" (any other value must lie in [0, 90])."""


def light_point_lights(model: mujoco.MjModel, scene: mujoco.MjvScene) -> int:
    """Turn the point lights of ``scene`` (filled from ``model``) into whole-sphere spots; returns
    how many were changed. Scenes without point lights (directional, spot, headlight) are left
    untouched, byte for byte."""
    if not np.any(model.light_type == _POINT):
        return 0  # most scenes: no per-light Python loop
    changed = 0
    for light in scene.lights[: scene.nlight]:
        # a headlight has id -1 and is directional; model lights carry their model id
        if light.type != _POINT or light.id < 0:
            continue
        light.type = _SPOT
        light.cutoff = WHOLE_SPHERE_CUTOFF_DEG
        light.exponent = 0.0
        light.attenuation[:] = model.light_attenuation[light.id]
        changed += 1
    return changed


__all__ = ["WHOLE_SPHERE_CUTOFF_DEG", "light_point_lights"]
