"""``BaseSample``: the base class of Isaac's interactive examples, run as the GUI would run it.

In Isaac Sim a sample is loaded by the Examples browser: LOAD makes a new stage and a World
with the sample's settings, calls ``setup_scene``, resets the World and awaits
``setup_post_load``; PLAY then starts the timeline. ``ambulo run`` does the same headless
(``run_sample``) and steps the World for the run's seconds.
"""

from __future__ import annotations

import asyncio
import math
from typing import Any

from ambulo.sim import World


class BaseSample:
    """Subclass it and override ``setup_scene`` (sync) and the ``setup_*`` coroutines."""

    def __init__(self) -> None:
        self._world: World | None = None
        self._current_tasks = None
        self._world_settings: dict[str, Any] = {"physics_dt": 1.0 / 60.0, "stage_units_in_meters": 1.0,
                                                "rendering_dt": 1.0 / 60.0}
        self._logging_info = ""

    def get_world(self) -> World | None:
        return self._world

    def set_world_settings(self, physics_dt: float | None = None, stage_units_in_meters: float | None = None,
                           rendering_dt: float | None = None) -> None:
        for key, value in (("physics_dt", physics_dt), ("stage_units_in_meters", stage_units_in_meters),
                           ("rendering_dt", rendering_dt)):
            if value is not None:
                self._world_settings[key] = value

    async def load_world_async(self) -> None:
        """The Examples browser's LOAD: a new World, ``setup_scene``, reset, ``setup_post_load``."""
        self._world = World(**self._world_settings)
        self.setup_scene()
        self._world.reset()
        self._world.pause()
        await self.setup_post_load()

    async def reset_async(self) -> None:
        """The RESET button: ``setup_pre_reset``, World reset, ``setup_post_reset``."""
        await self.setup_pre_reset()
        self._world.reset()
        self._world.pause()
        await self.setup_post_reset()

    def setup_scene(self) -> None:
        """Build the scene on ``self.get_world().scene`` (before the first reset)."""

    async def setup_post_load(self) -> None:
        """After LOAD's reset: objects are initialized; add physics callbacks here."""

    async def setup_pre_reset(self) -> None:
        """Before the RESET button's reset."""

    async def setup_post_reset(self) -> None:
        """After the RESET button's reset."""

    async def setup_post_clear(self) -> None:
        """After the stage is cleared."""

    def world_cleanup(self) -> None:
        """When the sample is closed."""

    def log_info(self, info: Any) -> None:
        self._logging_info += str(info) + "\n"


def run_sample(sample_cls: type[BaseSample], seconds: float) -> World:
    """Run ``sample_cls`` as Isaac's GUI would: LOAD, then PLAY for ``seconds`` of simulated time."""
    sample = sample_cls()
    asyncio.run(sample.load_world_async())
    world = sample.get_world()
    world.play()
    for _ in range(math.ceil(seconds / world.get_rendering_dt() - 1e-9)):
        world.step(render=True)
    sample.world_cleanup()
    return world


__all__ = ["BaseSample", "run_sample"]
