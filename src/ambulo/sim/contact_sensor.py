"""Isaac Sim's ``ContactSensor`` (``isaacsim.sensors.physics`` / ``omni.isaac.sensor``) on ambulo.

A face over ``ambulo.sensors.ContactSensor`` (one MuJoCo ``contact`` sensor with the net-force
reduction on the parent body, batched over worlds). The frame holds Isaac's keys: ``in_contact``
(bool), ``force`` (N, magnitude of the net contact force on the body, clamped to
``max_threshold``; 0 below ``min_threshold``), ``number_of_contacts`` (int), ``time`` (s) and
``physics_step``.

Isaac senses contacts within ``radius`` of the sensor; ambulo senses every contact of the
parent body (what a sensor covering the whole body reads), so ``radius`` is kept for
``get_radius`` only and a positive one logs a warning.
"""

from __future__ import annotations

import logging

from ambulo.sensors import ContactSensor as _ContactSensor
from ambulo.sensors import ContactSensorCfg

from .base_sensor import BaseSensor, due, period_from

log = logging.getLogger(__name__)

DEFAULT_MAX_THRESHOLD = 100000.0
"""N; Isaac's default ``max_threshold`` for a new sensor prim."""


class ContactSensor(BaseSensor):
    """Isaac's ``ContactSensor(prim_path, name, frequency, dt, translation, position,
    min_threshold, max_threshold, radius)``; ``prim_path`` is ``<body path>/<sensor name>``."""

    def __init__(self, prim_path: str, name: str = "contact_sensor", frequency: float | None = None,
                 dt: float | None = None, translation=None, position=None, min_threshold: float | None = None,
                 max_threshold: float | None = None, radius: float | None = None):
        body = prim_path.rstrip("/").rsplit("/", 1)[0]
        if not body:
            raise ValueError(f"contact sensor {prim_path!r} needs a parent body: pass '<body path>/<sensor name>'")
        self.translation = translation
        """Sensor position in the body frame (m), as given; the whole body is sensed."""
        self.position = position
        self._min = 0.0
        self._max = DEFAULT_MAX_THRESHOLD
        self.set_min_threshold(0.0 if min_threshold is None else min_threshold)
        self.set_max_threshold(DEFAULT_MAX_THRESHOLD if max_threshold is None else max_threshold)
        self._radius = -1.0
        self.set_radius(-1.0 if radius is None else radius)
        period = period_from(frequency, dt, "ContactSensor")
        sensor = _ContactSensor(ContactSensorCfg(prim_paths=(body,), name=prim_path))
        sensor.prim_path = prim_path
        if period is not None:
            sensor.update_period_s = period
        self._frame: dict = {"time": 0.0, "physics_step": 0.0}
        self._sample_s: float | None = None
        super().__init__(sensor, name)

    def _on_reset(self) -> None:
        self._sample_s = None

    def get_current_frame(self) -> dict:
        """``{"time", "physics_step", "in_contact", "force", "number_of_contacts"}`` of the latest
        sample (a new one when ``dt`` of simulated time passed); a paused sensor keeps its frame."""
        if not self.initialized or self._paused:
            return self._frame
        now = self._sim_time()
        if not due(self._sample_s, now, self.sensor.update_period_s):
            return self._frame
        data = self.sensor.get_current_frame()
        force = float(data.net_force_w[0, 0].norm())
        in_contact = bool(data.in_contact[0, 0]) and force >= self._min
        self._sample_s = now
        self._frame.update(time=now, physics_step=self._physics_step(), in_contact=in_contact,
                           force=min(force, self._max) if in_contact else 0.0,
                           number_of_contacts=int(data.num_contacts[0, 0]) if in_contact else 0)
        return self._frame

    def add_raw_contact_data_to_frame(self) -> None:
        raise NotImplementedError("raw contact data is not supported: read in_contact, force and "
                                  "number_of_contacts, or ambulo.sensors.ContactSensor for force vectors")

    # -- settings --------------------------------------------------------------------
    def get_min_threshold(self) -> float:
        return self._min

    def set_min_threshold(self, value: float) -> None:
        """N: weaker net forces read as no contact."""
        if not value >= 0:
            raise ValueError(f"min_threshold {value!r} must be >= 0 N, e.g. 0")
        self._min = float(value)

    def get_max_threshold(self) -> float:
        return self._max

    def set_max_threshold(self, value: float) -> None:
        """N: stronger net forces read as this value."""
        if not value > 0:
            raise ValueError(f"max_threshold {value!r} must be > 0 N, e.g. 100000")
        self._max = float(value)

    def get_radius(self) -> float:
        return self._radius

    def set_radius(self, value: float) -> None:
        if value > 0:
            log.warning("contact sensor radius %g m is not applied: ambulo senses every contact of the parent "
                        "body (pass radius=-1 to silence this)", value)
        self._radius = float(value)

    def get_frequency(self) -> int:
        return int(round(1.0 / self.get_dt()))

    def set_frequency(self, value: float) -> None:
        self.sensor.update_period_s = period_from(value, None, "ContactSensor")

    def get_dt(self) -> float:
        """s between samples (the physics step unless set)."""
        period = self.sensor.update_period_s
        if period == 0.0:
            world = self._world
            return world.get_physics_dt() if world is not None else float(self._require_engine().model.opt.timestep)
        return period

    def set_dt(self, value: float) -> None:
        self.sensor.update_period_s = period_from(None, value, "ContactSensor")


__all__ = ["ContactSensor"]
