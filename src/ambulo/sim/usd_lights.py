"""USD ``DomeLight`` prims as the World's environment light.

Isaac scripts light their stage with a dome: ``UsdLux.DomeLight.Define(stage, "/World/DomeLight")``
or ``prims.create_prim("/World/DomeLight", "DomeLight", attributes={"inputs:texture:file": "sky.hdr",
"inputs:intensity": 1000})``. MuJoCo's USD importer reads no UsdLux prims, so each dome authored
on the stage becomes, when the World compiles:

- an image light ``<path>/texture`` (``ambulo.render.ibl``) that the pbr and path tiers light with
  and show: the lat-long texture (or a uniform dome without one) times ``inputs:color`` (and the
  colour temperature when enabled), turned by the prim's world rotation, at intensity
  ``IMAGE_LIGHT_PER_NIT x inputs:intensity x 2^inputs:exposure``; a white Lambertian surface under
  a uniform dome then reads ``radiance = color x intensity x 2^exposure x IMAGE_LIGHT_PER_NIT x
  FILAMENT_EXPOSURE`` (linear) in both tiers;
- a light ``<path>`` with no diffuse part whose ``ambient`` is the dome's mean radiance encoded as
  the rasterizer's display values (sRGB), so the rasterizer shows a white surface about as bright
  as the other tiers do (its ambient is direction-free: no shading from the dome's bright side).

The texture is read z up in the prim's frame (the stage's up axis, as Isaac's renderer shows a
dome on a z-up stage). Formats other than lat-long (``automatic`` or ``latlong``) are refused in
one line.
"""

from __future__ import annotations

import os

import mujoco
import numpy as np

from ambulo.render.ibl import FILAMENT_EXPOSURE, IMAGE_LIGHT_PER_NIT, add_image_light, read_hdr, rotate_latlong
from ambulo.render.scene_description import linear_to_srgb

_LATLONG = ("automatic", "latlong")
_UNIFORM_PX = (4, 8)
"""Lat-long size of a dome without a texture (uniform: any size is exact)."""


def _texture_file(asset) -> str | None:
    """The texture's file: the asset path as USD resolved it, else as written (relative to the
    working directory: a stage's content is copied into memory, away from its file's folder)."""
    if asset is None or not asset.path:
        return None
    return asset.resolvedPath or asset.path


def dome_environment(prim) -> tuple[np.ndarray, float]:
    """(lat-long (H, W, 3) float32 linear texels in the world frame, image-light intensity) of a
    ``DomeLight`` prim (module docstring)."""
    from pxr import Usd, UsdGeom, UsdLux

    light = UsdLux.DomeLight(prim)
    path = str(prim.GetPath())
    fmt = str(light.GetTextureFormatAttr().Get() or "automatic")
    if fmt not in _LATLONG:
        raise ValueError(f"{path}: inputs:texture:format {fmt!r} is not read; give a latitude-longitude "
                         "texture (format 'latlong' or 'automatic')")
    color = np.asarray(light.GetColorAttr().Get() or (1.0, 1.0, 1.0), np.float32)
    if light.GetEnableColorTemperatureAttr().Get():
        color = color * np.asarray(UsdLux.BlackbodyTemperatureAsRgb(light.GetColorTemperatureAttr().Get()), np.float32)
    file = _texture_file(light.GetTextureFileAttr().Get())
    if file is None:
        texels = np.broadcast_to(color, (*_UNIFORM_PX, 3)).astype(np.float32)
    else:
        if not os.path.isfile(file):
            raise FileNotFoundError(f"{path}: inputs:texture:file {file!r} does not exist; give the path of a "
                                    "latitude-longitude .hdr (or .exr)")
        texels = read_hdr(file) * color
        m = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default()))
        rot = m[:3, :3].T  # USD's matrices act on row vectors
        rot = rot / np.linalg.norm(rot, axis=0, keepdims=True)
        if not np.allclose(rot, np.eye(3), atol=1e-9):
            texels = rotate_latlong(texels, rot)
    nits = float(light.GetIntensityAttr().Get()) * 2.0 ** float(light.GetExposureAttr().Get() or 0.0)
    return np.ascontiguousarray(texels, np.float32), IMAGE_LIGHT_PER_NIT * nits


def _mean_radiance(texels: np.ndarray) -> np.ndarray:
    """(3,) solid-angle mean of a lat-long image (rows weighted by sin(polar angle))."""
    h = texels.shape[0]
    weight = np.sin(np.pi * (np.arange(h) + 0.5) / h)[:, None, None]
    return (texels * weight).sum((0, 1)) / (weight.sum() * texels.shape[1])


def add_dome_lights(stage, spec: mujoco.MjSpec, root: str = "/World") -> int:
    """Add each ``DomeLight`` under ``root`` of the ``Usd.Stage`` ``stage`` to ``spec`` (names
    relative to ``root``, as the importer names the rest); returns how many."""
    from pxr import UsdLux

    count = 0
    for prim in stage.Traverse():
        if not prim.IsA(UsdLux.DomeLight) or not str(prim.GetPath()).startswith(root + "/"):
            continue
        name = str(prim.GetPath())[len(root) + 1:]
        texels, intensity = dome_environment(prim)
        add_image_light(spec, texels, name=f"{name}/texture", intensity=intensity)
        ambient = linear_to_srgb(_mean_radiance(texels) * intensity * FILAMENT_EXPOSURE)
        stand_in = spec.worldbody.add_light(name=name, type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                                            dir=[0.0, 0.0, -1.0], castshadow=False)
        stand_in.ambient, stand_in.diffuse, stand_in.specular = ambient.tolist(), [0.0] * 3, [0.0] * 3
        count += 1
    return count


__all__ = ["add_dome_lights", "dome_environment"]
