"""``SimulationApp``: Isaac's app object for standalone scripts, without Kit.

ambulo has no Kit application: the World steps MuJoCo itself and renders when asked. The
app keeps Isaac's contract for the loops scripts write: ``update()`` advances a playing
World by one rendering step (as Kit's update does with the timeline playing), and
``is_running()`` turns False once the run's time budget (``ambulo run --seconds``) is
spent, so ``while simulation_app.is_running():`` ends headless.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from typing import Any

from ambulo.sim.camera import set_default_renderer
from ambulo.sim.current import current_world_or_none

from . import carb

_run_seconds: float | None = None
"""Simulated seconds an ``is_running()`` loop may take; set by ``ambulo run --seconds``."""


@contextlib.contextmanager
def run_budget(seconds: float) -> Iterator[None]:
    """Inside the block, ``SimulationApp.is_running()`` loops end after ``seconds`` simulated."""
    global _run_seconds
    previous, _run_seconds = _run_seconds, float(seconds)
    try:
        yield
    finally:
        _run_seconds = previous


def advance_playing_world() -> None:
    """What a Kit app frame does to physics: a playing World steps once (rendering_dt)."""
    world = current_world_or_none()
    if world is not None and world.engine is not None and world.is_playing():
        world.step(render=True)


RENDER_MODES = {"RayTracedLighting": "pbr", "RaytracedLighting": "pbr", "PathTracing": "path",
                "raster": "raster", "pbr": "pbr", "path": "path"}
"""``SimulationApp``'s ``renderer`` key -> ambulo's camera tier: Isaac's real-time RTX mode is the
physically based rasterizer (Filament), its path tracer the path tier (Mitsuba); ambulo's own
names pass through."""


class SimulationApp:
    """Isaac's ``SimulationApp(launch_config)``; ``headless`` and the other keys are recorded.

    A ``renderer`` given in ``launch_config`` sets the colour tier of the cameras made afterwards
    (``RENDER_MODES``); left out, cameras keep the rasterizer (Isaac's default RTX mode would
    need Vulkan and cost ~10x per frame on a CPU, so it is not implied).
    """

    DEFAULT_LAUNCHER_CONFIG: dict[str, Any] = {
        "headless": True, "width": 1280, "height": 720, "renderer": "RayTracedLighting",
        "anti_aliasing": 3, "multi_gpu": False, "sync_loads": True, "open_usd": None,
    }

    def __init__(self, launch_config: dict[str, Any] | None = None, experience: str = ""):
        self.config = {**self.DEFAULT_LAUNCHER_CONFIG, **(launch_config or {})}
        if launch_config and "renderer" in launch_config:
            mode = launch_config["renderer"]
            if mode not in RENDER_MODES:
                raise ValueError(f"SimulationApp renderer {mode!r} is not one ambulo renders; use one of "
                                 f"{sorted(RENDER_MODES)}")
            set_default_renderer(RENDER_MODES[mode])
        self.experience = experience
        self._exiting = False
        self._loop_calls = 0

    @property
    def app(self) -> SimulationApp:
        """Kit's app interface; ``update()`` is the one method scripts call on it."""
        return self

    def update(self) -> None:
        """One app frame: a playing World advances by one rendering step."""
        advance_playing_world()

    def is_running(self) -> bool:
        """True until ``close()``, or until the run's time budget is spent."""
        if self._exiting:
            return False
        if _run_seconds is None:
            return True
        world = current_world_or_none()
        if world is None or world.engine is None:
            return True
        # counting loop turns too ends scripts that reset the World's clock inside the loop
        self._loop_calls += 1
        max_calls = math.ceil(_run_seconds / world.get_rendering_dt()) + 1
        return world.current_time < _run_seconds and self._loop_calls <= max_calls

    def is_exiting(self) -> bool:
        return self._exiting

    def close(self, wait_for_replicator: bool = True, skip_cleanup: bool = False) -> None:
        self._exiting = True

    def set_setting(self, setting: str, value: Any) -> None:
        carb.get_settings().set(setting, value)

    def reset_render_settings(self) -> None:
        """Render settings are the renderer's defaults already."""


__all__ = ["SimulationApp", "advance_playing_world", "run_budget"]
