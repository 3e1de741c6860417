"""Live scalar curves beside the scene (training reward, episode length, a task's criteria).

The caller (a training loop, on its own thread) only appends ``(step, {name: value})`` to a list
under a lock held for the append: it never waits for the page. The viewer's streaming thread
drains that list at its read-out rate and redraws one uPlot curve per name (names differ in
scale, so each has its own plot, created the first time the name is seen).

A long run keeps its whole history at a bounded cost: once a curve holds ``max_points`` samples,
every other old one is dropped (the curve keeps its shape at half the resolution).
"""

from __future__ import annotations

import math
import threading

import numpy as np

MAX_POINTS = 2000
"""Samples kept per curve before it is thinned by half (uPlot draws 2000 points at no cost)."""

COLOURS = ("#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf")


class ScalarLog:
    """Named scalar series, appended from any thread, read by the viewer's streaming thread.

    Args:
      max_points: samples kept per name before thinning (>= 4).
    """

    def __init__(self, max_points: int = MAX_POINTS):
        if max_points < 4:
            raise ValueError(f"max_points is {max_points}: keep at least 4 samples per curve")
        self.max_points = max_points
        self._lock = threading.Lock()
        self._pending: list[tuple[float, dict[str, float]]] = []
        self._series: dict[str, tuple[list[float], list[float]]] = {}

    def add(self, step: float, scalars: dict[str, float]) -> None:
        """Queue ``scalars`` at x = ``step`` (cheap: a conversion and a list append under a lock).
        Non-finite values are dropped (uPlot would break the line there anyway)."""
        values = {}
        for name, value in scalars.items():
            value = float(value)
            if math.isfinite(value):
                values[str(name)] = value
        if not values:
            return
        with self._lock:
            self._pending.append((float(step), values))

    def drain(self) -> set[str]:
        """Move queued samples into the series (streaming thread); returns the names that changed."""
        with self._lock:
            pending, self._pending = self._pending, []
        changed: set[str] = set()
        for step, values in pending:
            for name, value in values.items():
                xs, ys = self._series.setdefault(name, ([], []))
                xs.append(step)
                ys.append(value)
                if len(xs) > self.max_points:  # keep the newest sample, thin the rest by half
                    del xs[-2::-2], ys[-2::-2]
                changed.add(name)
        return changed

    def series(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(steps, values) of ``name`` as drained so far."""
        xs, ys = self._series[name]
        return np.asarray(xs, dtype=float), np.asarray(ys, dtype=float)

    @property
    def names(self) -> list[str]:
        return list(self._series)


class CurvePanel:
    """One uPlot per name in a "Curves" folder of the page; ``update`` runs on the streaming thread."""

    def __init__(self, server, log: ScalarLog, x_label: str = "step"):
        self.server, self.log, self.x_label = server, log, x_label
        self.plots: dict = {}
        self._folder = None

    def update(self) -> None:
        for name in sorted(self.log.drain()):
            x, y = self.log.series(name)
            if len(x) < 2:  # uPlot needs two points for a line; the first waits for the second
                continue
            plot = self.plots.get(name)
            if plot is None:
                if self._folder is None:
                    self._folder = self.server.gui.add_folder("Curves")
                colour = COLOURS[len(self.plots) % len(COLOURS)]
                with self._folder:
                    plot = self.server.gui.add_uplot(
                        data=(x, y), series=({"label": self.x_label}, {"label": name, "stroke": colour, "width": 2}),
                        title=name, aspect=2.0)
                self.plots[name] = plot
            else:
                plot.data = (x, y)
