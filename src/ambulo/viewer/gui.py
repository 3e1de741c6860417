"""The page's side panel: status and body positions, pause/step/reset, the watched world, the
camera follow, the velocity command (sliders and keys), body visibility and the episode-return
curve. Callbacks only write ``Controls`` or viser state; nothing here touches the simulation."""

from __future__ import annotations

from collections import deque

import numpy as np
import viser

from .controls import COMMAND_LIMITS, KEY_STEPS, Controls
from .layout import GRID_SIZES

SPEEDS = ("max", "0.25x", "0.5x", "1x", "2x", "4x")
"""The simulation speeds the page offers."""

RETURN_CURVE_POINTS = 600
"""Samples of the episode-return curve kept on the page (20 s at 30 frames/s)."""


class Panel:
    """The GUI handles of one viewer (shared by every connected page)."""

    def __init__(self, server: viser.ViserServer, controls: Controls, *, root_names: list[str],
                 follow: bool, show_command: bool, show_return: bool, can_reset: bool, spacing_m: float = 2.0):
        gui, self.controls = server.gui, controls
        self.status = gui.add_markdown("starting")
        with gui.add_folder("Simulation"):
            self.pause = gui.add_button("Pause", hint="pause or resume the simulation (key P)")
            self.step = gui.add_button("Step", hint="one simulation step while paused")
            self.reset = gui.add_button("Reset", hint="reset the watched world", visible=can_reset)
            self.speed = gui.add_dropdown("Speed", SPEEDS, initial_value=speed_label(controls.speed),
                                          hint="simulated time per wall time (max: as fast as it runs)")
        with gui.add_folder("Watch"):
            self.world = gui.add_number("World", 0, min=0, max=max(controls.num_worlds - 1, 0), step=1,
                                        hint=f"which of the {controls.num_worlds} worlds to show")
            self.follow = gui.add_checkbox("Follow robot", follow, hint="the camera follows the first robot")
            sizes = [str(n) for n in GRID_SIZES if n <= controls.num_worlds]
            shown = str(len(controls.worlds()))
            self.grid = gui.add_dropdown("Worlds drawn", sizes if shown in sizes else [*sizes, shown],
                                         initial_value=shown, visible=controls.num_worlds > 1,
                                         hint="a grid of worlds side by side: the watched one, then the next ones")
            self.spacing = gui.add_number("Grid spacing m", round(spacing_m, 2), min=0.5, step=0.5,
                                          visible=controls.num_worlds > 1, hint="distance between drawn worlds")
        self.sliders = []
        if show_command:
            with gui.add_folder("Velocity command"):
                self.teleop = gui.add_checkbox("Teleoperate", False, hint="keys W/S, A/D, Q/E change it; X stops")
                for label, (lo, hi), step in zip(("vx m/s", "vy m/s", "yaw rad/s"), COMMAND_LIMITS,
                                                 (0.05, 0.05, 0.1)):
                    self.sliders.append(gui.add_slider(label, lo, hi, step, 0.0))
        with gui.add_folder("Bodies"):
            self.visible = {name: gui.add_checkbox(f"show {name}", True) for name in root_names}
        self.readout = gui.add_markdown("")
        self.returns: deque[tuple[float, float]] = deque(maxlen=RETURN_CURVE_POINTS)
        self.curve = None
        if show_return:
            self.curve = gui.add_uplot(data=(np.zeros(2), np.zeros(2)),
                                       series=({"label": "sim time s"}, {"label": "episode return", "stroke": "red"}),
                                       title="Episode return (watched world)", aspect=1.6)
        self._wire(server)

    def _wire(self, server: viser.ViserServer) -> None:
        controls = self.controls

        @self.pause.on_click
        def _(_event) -> None:
            self.toggle_pause()

        self.step.on_click(lambda _e: controls.step_once())
        self.reset.on_click(lambda _e: controls.request_reset())
        self.speed.on_update(lambda _e: setattr(controls, "speed", speed_value(self.speed.value)))
        self.world.on_update(lambda _e: controls.watch(int(self.world.value)))
        self.grid.on_update(lambda _e: controls.show(int(self.grid.value)))
        if self.sliders:
            def from_sliders(_event) -> None:
                if self.teleop.value:
                    controls.set_command([s.value for s in self.sliders])
                else:
                    controls.release_command()

            for handle in (self.teleop, *self.sliders):
                handle.on_update(from_sliders)
            for key in (*KEY_STEPS, "X"):
                command = server.gui.add_command(f"command {key}", description="teleoperate the robot", hotkey=key)
                command.on_trigger(lambda _e, key=key: self.press(key))
        server.gui.add_command("pause", description="pause or resume", hotkey="P").on_trigger(
            lambda _e: self.toggle_pause())

    def spacing_m(self) -> float:
        """The grid's spacing, m (the page's field; at least 0.5 m)."""
        return max(0.5, float(self.spacing.value))

    def toggle_pause(self) -> None:
        paused = not self.controls.paused
        self.controls.set_paused(paused)
        self.pause.label = "Resume" if paused else "Pause"

    def press(self, key: str) -> None:
        """A teleoperation key: the command changes and the sliders show it."""
        command = self.controls.nudge(key)
        self.teleop.value = True
        for slider, value in zip(self.sliders, command):
            slider.value = float(value)
        self.controls.set_command(command)  # the slider callbacks above ran with the old values

    def show_return(self, time_s: float, episode_return: float) -> None:
        if self.curve is None:
            return
        if self.returns and time_s < self.returns[-1][0]:
            self.returns.clear()  # the watched world was reset or changed
        self.returns.append((time_s, episode_return))
        if len(self.returns) >= 2:
            data = np.asarray(self.returns)
            self.curve.data = (data[:, 0], data[:, 1])


def speed_label(speed: float | None) -> str:
    return "max" if speed is None else f"{speed:g}x"


def speed_value(label: str) -> float | None:
    return None if label == "max" else float(label.rstrip("x"))
