"""Isaac's ``utils.viewports``: aim the World's viewport camera (recordings, viewer) from eye to
target (``set_camera_view``) and read a viewport's intrinsics (``get_intrinsics_matrix``)."""

from __future__ import annotations

import math

import numpy as np

from .current import current_world


def set_camera_view(eye, target, camera_prim_path: str = "/OmniverseKit_Persp", world=None) -> None:
    """Place the viewport camera at ``eye`` looking at ``target`` (world frame, m).

    ``camera_prim_path`` naming a camera sensor in the scene aims that camera
    instead (its ``set_camera_view``).
    """
    world = world or current_world("setting the camera view")
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    if eye.shape != (3,) or target.shape != (3,):
        raise ValueError("eye and target are 3-vectors in metres")
    offset = eye - target
    distance = float(np.linalg.norm(offset))
    if distance < 1e-9:
        raise ValueError("eye and target coincide; the camera needs a direction to look")
    if camera_prim_path != "/OmniverseKit_Persp":
        for obj in world.scene.objects():
            if getattr(obj, "prim_path", None) == camera_prim_path and hasattr(obj, "set_camera_view"):
                obj.set_camera_view(eye, target)
                return
        raise KeyError(f"no camera at {camera_prim_path!r}; use '/OmniverseKit_Persp' for the viewport")
    cam = world.viewport_camera
    cam.lookat[:] = target
    cam.distance = distance
    # MuJoCo's free camera: azimuth about +z from +x, elevation negative looking down
    cam.azimuth = math.degrees(math.atan2(-offset[1], -offset[0]))
    cam.elevation = -math.degrees(math.asin(offset[2] / distance))


def get_intrinsics_matrix(viewport_api, world=None) -> np.ndarray:
    """(3, 3) K of the camera a viewport shows (+x right, +y down in the image), as Isaac's
    ``viewports.get_intrinsics_matrix(viewport_api)``.

    ``viewport_api`` is a camera object (its ``get_intrinsics_matrix()``), or Isaac's viewport
    handle: anything with ``camera_path`` and ``get_texture_resolution()`` -> (W, H). For the
    viewport camera ``/OmniverseKit_Persp`` (MuJoCo's free camera, square pixels) fy = (H / 2) /
    tan(fovy / 2) with the model's ``visual/global fovy``, fx = fy; for a camera of the scene,
    its focal length and apertures at the viewport's resolution. The principal point is (W/2, H/2).
    """
    if hasattr(viewport_api, "get_intrinsics_matrix"):
        return np.asarray(viewport_api.get_intrinsics_matrix(), dtype=float)
    if not (hasattr(viewport_api, "camera_path") and hasattr(viewport_api, "get_texture_resolution")):
        raise TypeError(f"get_intrinsics_matrix takes a camera or a viewport handle (camera_path, "
                        f"get_texture_resolution()), got {type(viewport_api).__name__}; pass the Camera")
    width, height = (int(v) for v in viewport_api.get_texture_resolution())
    path = str(viewport_api.camera_path)
    world = world or current_world("reading viewport intrinsics")
    if path == "/OmniverseKit_Persp":
        if world.model is None:
            raise RuntimeError("the viewport's field of view comes from the model: call world.reset() first")
        fy = 0.5 * height / math.tan(math.radians(float(world.model.vis.global_.fovy)) / 2)
        fx = fy
    else:
        camera = next((o for o in world.scene.objects() if getattr(o, "prim_path", None) == path
                       and hasattr(o, "get_focal_length")), None)
        if camera is None:
            raise KeyError(f"no camera at {path!r} in world.scene; add the Camera, or use '/OmniverseKit_Persp'")
        fx = width * camera.get_focal_length() / camera.get_horizontal_aperture()
        fy = height * camera.get_focal_length() / camera.get_vertical_aperture()
    return np.array([[fx, 0.0, width * 0.5], [0.0, fy, height * 0.5], [0.0, 0.0, 1.0]])
