"""set_camera_view: aim the World's viewport camera (recordings, viewer) from eye to target."""

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
