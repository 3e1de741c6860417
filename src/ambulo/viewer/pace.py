"""Timing of the viewer's loops: ``Pace`` holds a simulation to a speed, simulated seconds per wall
second (the page's Speed); ``Ticks`` keeps a streaming loop at its capped rate."""

from __future__ import annotations

import threading
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


class Ticks:
    """Deadlines ``period_s`` apart for a streaming loop: a late wake-up (a busy machine wakes a
    sleeping thread milliseconds late) shortens the next wait instead of delaying every later frame,
    so the frames keep the capped rate (a relative sleep gave 27 frames/s for a 30 Hz cap on a
    loaded 2-core machine)."""

    def __init__(self, period_s: float):
        self.period_s = period_s
        self.next_s = time.perf_counter()

    def wait(self, stop: threading.Event) -> None:
        """Sleep until the next deadline or until ``stop`` is set."""
        self.next_s += self.period_s
        now = time.perf_counter()
        if self.next_s < now - self.period_s:  # more than a tick behind (a pause, a slow send): start afresh
            self.next_s = now
        stop.wait(max(0.0, self.next_s - now))
