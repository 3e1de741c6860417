"""``Pace``: holds a simulation to a speed, simulated seconds per wall second (the page's Speed)."""

from __future__ import annotations

import time


class Pace:
    """Sleeps in the simulation thread so that it runs at ``speed`` x real time at most."""

    def __init__(self) -> None:
        self.restart()

    def restart(self) -> None:
        self._speed, self._sim_s, self._wall0 = None, 0.0, time.perf_counter()

    def hold(self, dt_s: float, speed: float | None) -> None:
        if speed != self._speed:
            self.restart()
            self._speed = speed
        if speed is None:
            return
        self._sim_s += dt_s
        ahead_s = self._sim_s / speed - (time.perf_counter() - self._wall0)
        if ahead_s > 0:
            time.sleep(ahead_s)
