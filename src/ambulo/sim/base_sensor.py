"""What Isaac's sensor classes share on ambulo: a named face over one batched ambulo sensor.

Isaac creates a sensor prim when a sensor object is constructed, so tutorials often never
``world.scene.add`` a camera. The same holds here: constructing a sensor while a World exists
hands it to that World's lifecycle (``world.sim.add``: built into the stage now, initialized
at the next ``world.reset()``), and a later ``world.scene.add(sensor)`` only registers its
name. The per-step work stays in the wrapped ``ambulo.sensors`` object (``self.sensor``); this
class implements the ``ambulo.core.Component`` protocol by delegating to it.

Isaac's ``initialize()`` takes no arguments and users call it after ``world.reset()``; the
lifecycle calls ``initialize(engine)``. Both go through ``initialize`` here.
"""

from __future__ import annotations

import logging
import math

from ambulo.engine import sim_time_s
from ambulo.utils.checks import check_positive

from .current import current_world_or_none
from .transaction import atomic_constructor

log = logging.getLogger(__name__)


def period_from(frequency, dt, what: str) -> float | None:
    """Seconds between samples from Isaac's ``frequency`` (Hz) or ``dt`` (s); None if neither."""
    if frequency is not None and dt is not None:
        raise ValueError(f"{what}: pass frequency= or dt=, not both")
    if frequency is not None:
        return 1.0 / check_positive("frequency", frequency, "pass Hz > 0, e.g. frequency=20")
    if dt is not None:
        return check_positive("dt", dt, "pass seconds > 0, e.g. dt=0.05")
    return None


def due(last_s: float | None, now_s: float, period_s: float) -> bool:
    """Whether a sample taken at ``last_s`` is stale at ``now_s``: samples fall on the grid of
    multiples of ``period_s`` (each new period's first read or step takes one, so its time is the
    period's start or just after it); ``period_s`` 0 takes one at every new time."""
    if last_s is None or now_s < last_s:  # never sampled, or the clock was reset
        return True
    if period_s <= 0.0:
        return now_s != last_s
    return math.floor(now_s / period_s + 1e-9) != math.floor(last_s / period_s + 1e-9)


class BaseSensor:
    """An Isaac-named sensor (``name``, ``prim_path``) over the ambulo sensor ``self.sensor``."""


    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        atomic_constructor(cls)  # a failing constructor leaves the stage as it was
    def __init__(self, sensor, name: str):
        if not isinstance(name, str) or not name:
            raise ValueError(f"sensor name {name!r} must be a non-empty string; pass e.g. name='camera'")
        self.sensor = sensor
        """The batched ``ambulo.sensors`` object that does the work (N = 1 in Isaac scripts)."""
        self.name = name
        self.prim_path = sensor.prim_path
        self._world = None
        self._paused = False
        world = current_world_or_none()
        if world is not None:
            self._register(world)

    def _register(self, world) -> None:
        world.sim.add(self)  # refuses a second sensor of the same name, naming the fix
        self._world = world

    # -- ambulo's component lifecycle ---------------------------------------------
    def build(self, spec) -> None:
        self.sensor.build(spec)

    def initialize(self, engine=None) -> None:
        """Isaac's ``initialize()`` (no arguments; after ``world.reset()``) or the lifecycle's
        ``initialize(engine)`` (``world.reset()`` calls it when it compiles the stage)."""
        if engine is not None:
            self._world = self._world or current_world_or_none()
            self._before_initialize(engine)
            self.sensor.initialize(engine)
            self._after_initialize()
            return
        world = self._world or current_world_or_none()
        if world is None:
            raise RuntimeError(f"{type(self).__name__} {self.name!r} is on no World; create the World "
                               "before the sensor, or world.scene.add(sensor)")
        if world.sim.components.get(self.name) is not self:
            self._register(world)
        if world.engine is not None and self.sensor.engine is None:
            raise RuntimeError(f"{type(self).__name__} {self.name!r} was added after the last world.reset(); "
                               "call world.reset() before initialize()")
        self._world = world
        self._on_user_initialize()

    def update(self, dt_s: float) -> None:
        self.sensor.update(dt_s)

    def reset(self, world_ids=None) -> None:
        self.sensor.reset(world_ids)
        self._on_reset()

    # -- hooks for subclasses ------------------------------------------------------
    def _before_initialize(self, engine) -> None:
        """Before the wrapped sensor resolves its ids (e.g. turn a world pose into an offset)."""

    def _after_initialize(self) -> None:
        """After the wrapped sensor is initialized against a new engine."""

    def _on_user_initialize(self) -> None:
        """What Isaac's ``initialize()`` does beyond what the lifecycle did."""

    def _on_reset(self) -> None:
        """After ``world.reset()`` put the worlds back to their initial state."""

    # -- Isaac's common members ------------------------------------------------------
    @property
    def initialized(self) -> bool:
        return self.sensor.engine is not None

    def _require_engine(self):
        if self.sensor.engine is None:
            raise RuntimeError(f"{type(self).__name__} {self.name!r} has no data yet; call world.reset() "
                               "(and then initialize()) before reading it")
        return self.sensor.engine

    def _sim_time(self) -> float:
        return sim_time_s(self._require_engine())

    def _physics_step(self) -> float:
        """Physics steps since the last reset, as Isaac reports it (a float)."""
        world = self._world
        if world is not None and world.engine is self.sensor.engine:
            return float(world.current_time_step_index)
        return float(round(self._sim_time() / float(self.sensor.engine.model.opt.timestep)))

    def pause(self) -> None:
        """Stop refreshing the frame: ``get_current_frame`` keeps the last sample."""
        self._paused = True

    def resume(self) -> None:
        self._paused = False

    def is_paused(self) -> bool:
        return self._paused

    def post_reset(self) -> None:
        """Isaac's per-object reset hook; the World's reset already reset the wrapped sensor."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}(prim_path={self.prim_path!r}, name={self.name!r})"


atomic_constructor(BaseSensor)

__all__ = ["BaseSensor", "due", "period_from"]
