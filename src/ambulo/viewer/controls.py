"""What the page asks of the simulation, handed across threads: pause, single steps, a reset, the
watched world, the teleoperated velocity command. The browser's callbacks (viser's thread pool)
write it; the simulation thread reads it inside its step; a lock guards the few fields together.
"""

from __future__ import annotations

import threading

import numpy as np

COMMAND_LIMITS = ((-1.0, 1.0), (-0.5, 0.5), (-1.0, 1.0))
"""(low, high) of the page's (vx m/s, vy m/s, yaw rate rad/s): the walking policy's training
ranges (``envs.commands.VelocityCommandCfg``' defaults)."""

KEY_STEPS = {"W": (0, 0.1), "S": (0, -0.1), "A": (1, 0.1), "D": (1, -0.1), "Q": (2, 0.2), "E": (2, -0.2)}
"""Teleoperation keys: key -> (command component, change per press). X zeroes the command."""


class Controls:
    """The page's requests; every method is safe from any thread."""

    def __init__(self, num_worlds: int, speed: float | None = None):
        self.num_worlds = num_worlds
        self.speed = speed
        """Simulated seconds per wall second the simulation is held to, or None: as fast as it runs."""
        self._lock = threading.Lock()
        self._resume = threading.Condition(self._lock)
        self._paused = False
        self._steps_allowed = 0
        self._reset = False
        self._world = 0
        self._shown = 1
        self._teleop = False
        self._command = np.zeros(3)
        self.closed = False

    # -- written by the page ------------------------------------------------------------------
    def set_paused(self, paused: bool) -> None:
        with self._lock:
            self._paused = bool(paused)
            self._resume.notify_all()

    def step_once(self) -> None:
        with self._lock:
            self._steps_allowed += 1
            self._resume.notify_all()

    def request_reset(self) -> None:
        with self._lock:
            self._reset = True
            self._resume.notify_all()

    def watch(self, world: int) -> None:
        with self._lock:
            self._world = min(max(int(world), 0), self.num_worlds - 1)
            self._resume.notify_all()

    def show(self, count: int) -> None:
        """Draw ``count`` worlds side by side (a grid), from the watched one on (1: it alone)."""
        with self._lock:
            self._shown = min(max(int(count), 1), self.num_worlds)

    def set_command(self, command) -> np.ndarray:
        """Teleoperate with ``command`` (clipped to ``COMMAND_LIMITS``); returns what was kept."""
        clipped = np.array([np.clip(c, lo, hi) for c, (lo, hi) in zip(command, COMMAND_LIMITS)], dtype=float)
        with self._lock:
            self._command, self._teleop = clipped, True
        return clipped.copy()

    def nudge(self, key: str) -> np.ndarray:
        """A teleoperation key press (``KEY_STEPS``, or X to stop); returns the new command."""
        with self._lock:
            command = self._command.copy()
        if key == "X":
            command[:] = 0.0
        else:
            axis, change = KEY_STEPS[key]
            command[axis] = round(command[axis] + change, 6)
        return self.set_command(command)

    def release_command(self) -> None:
        with self._lock:
            self._teleop = False

    def close(self) -> None:
        with self._lock:
            self.closed, self._paused = True, False
            self._resume.notify_all()

    # -- read by the simulation thread --------------------------------------------------------
    @property
    def world(self) -> int:
        return self._world

    def worlds(self) -> list[int]:
        """The worlds drawn: the watched one, then the next ones (wrapping) up to the grid's size."""
        with self._lock:
            return [(self._world + k) % self.num_worlds for k in range(self._shown)]

    @property
    def paused(self) -> bool:
        return self._paused

    def command(self) -> np.ndarray | None:
        """The teleoperated command, or None while the page does not teleoperate."""
        with self._lock:
            return self._command.copy() if self._teleop else None

    def take_reset(self) -> bool:
        with self._lock:
            reset, self._reset = self._reset, False
            return reset

    def wait_while_paused(self, on_wake) -> None:
        """Block the simulation thread while paused; ``on_wake()`` runs at each wake-up (a new frame
        for the page, a reset) while the lock is free. Returns for a single step or on resume."""
        while True:
            with self._lock:
                if not self._paused or self.closed:
                    return
                if self._steps_allowed > 0:
                    self._steps_allowed -= 1
                    return
                self._resume.wait(timeout=0.05)
            on_wake()
