"""Recorder: render a world's viewport camera headless into an MP4 (imageio-ffmpeg)."""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np

from ..render import OffscreenRenderer, RenderSettings, fast_render_settings
from .world import World


class Recorder:
    """Write frames of world ``world_index`` seen from ``world.viewport_camera`` to ``path``.

    Call ``capture()`` after steps; frames are kept at ``fps`` of simulated time
    (captures closer together than 1/fps are skipped). The file is written to
    ``<stem>.part<suffix>`` and renamed on ``close()``, so an interrupted run never
    leaves a truncated MP4 under the final name.
    """

    def __init__(self, world: World, path: str | os.PathLike, *, width: int = 640, height: int = 480,
                 fps: int = 30, world_index: int = 0, settings: RenderSettings | None = None):
        import imageio.v2 as imageio  # noqa: PLC0415 - optional heavy import

        if world.engine is None:
            raise RuntimeError("reset the World before recording it")
        self.world, self.path, self.fps = world, Path(path), fps
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = self.path.with_name(self.path.stem + ".part" + self.path.suffix)
        # shadows and multisampling off: on a software rasterizer they cost 10x
        self._renderer = OffscreenRenderer(world.model, width, height, settings or fast_render_settings())
        self._data = mujoco.MjData(world.model)
        self._world_index = world_index
        self._writer = imageio.get_writer(self._tmp, format="FFMPEG", fps=fps, codec="libx264",
                                          quality=7, macro_block_size=8)
        self._next_time = -1.0
        self.num_frames = 0

    def capture(self) -> None:
        now = self.world.current_time
        if now + 1e-9 < self._next_time:
            return
        self._next_time = now + 1.0 / self.fps
        self.world.engine.get_data(self._world_index, self._data)
        self._renderer.update_view(self.world.model, self._data, self.world.viewport_camera)
        self._writer.append_data(np.ascontiguousarray(self._renderer.render_rgb()))
        self.num_frames += 1

    def close(self) -> Path:
        self._writer.close()
        self._renderer.close()
        os.replace(self._tmp, self.path)
        return self.path

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc) -> None:
        if exc[0] is None:
            self.close()
        else:
            self._writer.close()
            self._renderer.close()
