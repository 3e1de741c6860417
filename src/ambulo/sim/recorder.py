"""Recorder: render a world's viewport camera headless into an MP4 (``render.video``)."""

from __future__ import annotations

import os
from pathlib import Path

import mujoco

from ..render import OffscreenRenderer, RenderSettings, fast_render_settings
from ..render.video import VideoWriter
from .world import World


class Recorder:
    """Write frames of world ``world_index`` seen from ``world.viewport_camera`` to ``path``.

    Call ``capture()`` after steps; frames are kept at ``fps`` of simulated time
    (captures closer together than 1/fps are skipped). The file is written to a hidden
    temporary and renamed on ``close()`` (``render.video.VideoWriter``), so an interrupted
    run never leaves a truncated MP4 under the final name. ``renderer``: "raster" (MuJoCo's
    rasterizer) or "pbr" (Filament, ``render.pbr``) draws the frames; the path tier renders
    model cameras only (a viewport camera is free) and is refused.
    """

    def __init__(self, world: World, path: str | os.PathLike, *, width: int = 640, height: int = 480,
                 fps: int = 30, world_index: int = 0, settings: RenderSettings | None = None,
                 renderer: str = "raster"):
        if world.engine is None:
            raise RuntimeError("reset the World before recording it")
        if renderer not in ("raster", "pbr"):
            raise ValueError(f"a Recorder draws with renderer 'raster' or 'pbr', not {renderer!r} (the path tier "
                             "renders a model camera: use a Camera(renderer='path'))")
        self.world, self.path, self.fps = world, Path(path), fps
        self._writer = VideoWriter(self.path, fps=fps, quality=7)  # checks ffmpeg before any rendering
        # shadows and multisampling off: on a software rasterizer they cost 10x
        self._renderer = OffscreenRenderer(world.model, width, height, settings or fast_render_settings())
        self._pbr = None
        if renderer == "pbr":
            from ..render.pbr import PbrRenderer

            self._pbr = PbrRenderer(world.model, width, height)
        self._data = mujoco.MjData(world.model)
        self._world_index = world_index
        self._next_time = -1.0
        self.num_frames = 0

    def capture(self) -> None:
        now = self.world.current_time
        if now + 1e-9 < self._next_time:
            return
        self._next_time = now + 1.0 / self.fps
        self.world.engine.get_data(self._world_index, self._data)
        self._renderer.update_view(self.world.model, self._data, self.world.viewport_camera)
        if self._pbr is None:
            self._writer.append(self._renderer.render_rgb())
        else:  # the rasterizer's view of the viewport camera: the same frustum
            self._writer.append(self._pbr.render(self._data, self._renderer.scene.camera[0]))
        self.num_frames += 1

    def close(self) -> Path:
        self._renderer.close()
        return self._writer.close()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc) -> None:
        if exc[0] is None:
            self.close()
        else:
            self._writer.abort()
            self._renderer.close()
