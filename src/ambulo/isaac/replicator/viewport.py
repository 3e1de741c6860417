"""``omni.kit.viewport.utility.get_active_viewport``: the viewport of the current World.

Kit's active viewport shows the stage through ``/OmniverseKit_Persp``; in ambulo that camera is
the World's ``viewport_camera`` (aimed with ``set_camera_view``). The viewport API object keeps
the texture resolution that ``SyntheticDataHelper`` renders at (Kit's default 1280 x 720).
"""

from __future__ import annotations

import sys

from ambulo.sim.current import current_world

from .errors import unsupported

VIEWPORT_CAMERA = "/OmniverseKit_Persp"


class ViewportAPI:
    """What ``get_active_viewport()`` returns: camera path and render resolution of the viewport."""

    def __init__(self):
        self._resolution = (1280, 720)

    @property
    def camera_path(self) -> str:
        return VIEWPORT_CAMERA

    @camera_path.setter
    def camera_path(self, path: str) -> None:
        self.set_active_camera(path)

    def get_active_camera(self) -> str:
        return VIEWPORT_CAMERA

    def set_active_camera(self, path: str) -> None:
        if str(path) != VIEWPORT_CAMERA:
            raise unsupported(f"viewport camera {path!r}", f"the viewport shows {VIEWPORT_CAMERA}; aim it with "
                                                           "set_camera_view(eye, target)")

    @property
    def resolution(self) -> tuple[int, int]:
        return self._resolution

    @resolution.setter
    def resolution(self, value) -> None:
        width, height = (int(v) for v in value)
        if width < 1 or height < 1:
            raise ValueError(f"viewport resolution must be (width, height) >= 1, got {value!r}")
        self._resolution = (width, height)

    def set_texture_resolution(self, value) -> None:
        self.resolution = value

    def get_texture_resolution(self) -> tuple[int, int]:
        return self._resolution

    @property
    def world(self):
        return current_world("rendering the viewport")


_viewport: tuple[object, ViewportAPI] | None = None


def get_active_viewport(window_name: str | None = None) -> ViewportAPI:
    """The one viewport of this script run (a new run starts with Kit's default resolution)."""
    global _viewport
    owner = sys.modules.get("omni.kit.viewport.utility")
    if _viewport is None or _viewport[0] is not owner:
        _viewport = (owner, ViewportAPI())
    return _viewport[1]
