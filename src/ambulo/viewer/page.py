"""``PageServer``: the viser side of the web viewer, the page's server and its streaming thread.

It draws what the simulation side hands it, through three objects it shares with that side (in
the same process) or with ``remote``'s link (in the viewer's own process): a ``FrameExchange``
of the drawn worlds' poses, an ``OverlayFeed`` of what features showed and a ``ScalarLog`` of the
curves; the page's requests go to a ``Controls``. The model's shapes are sent once per model
(``set_model``); then the streaming thread sends the poses at ``rate_hz`` at most, as one atomic
update of the moving bodies' frames.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass

import mujoco
import numpy as np
import viser

from .camera import CameraPose
from .controls import Controls
from .curves import CurvePanel, ScalarLog
from .feed import OverlayFeed
from .frames import FrameExchange
from .geometry import body_name, geom_shapes, root_bodies, subtree
from .gui import Panel, speed_label
from .layout import scene_spacing_m
from .overlays import Overlays
from .pace import Ticks
from .scene import GridScene
from .sensor_feeds import feed_scans

log = logging.getLogger(__name__)

READOUT_PERIOD_S = 0.2
"""s between updates of the panel's text and curve (text at 30 Hz only costs bandwidth)."""
AMBIENT_INTENSITY = 0.6
"""Ambient light of the page (three.js units; 0.6 keeps a wall turned from the lights a mid grey)."""


@dataclass(frozen=True)
class ModelInfo:
    """What the page needs besides the compiled model, read on the simulation side.

    Attributes:
      xpos_w, xmat_w: (nbody, 3) and (nbody, 9) body poses of world 0 at compile time (the grid's
        spacing is the posed scene's extent).
      camera: the page's opening camera.
      follow, has_command, show_return, can_reset: the target's defaults (``targets``).
      camera_sensors: camera sensors pose the model's cameras per world (frames then carry them).
    """

    xpos_w: np.ndarray
    xmat_w: np.ndarray
    camera: CameraPose
    follow: bool
    has_command: bool
    show_return: bool
    can_reset: bool
    camera_sensors: bool


class PageServer:
    """A viser server on ``host:port`` drawing the frames of ``exchange`` (see the module)."""

    def __init__(self, controls: Controls, exchange: FrameExchange, feed: OverlayFeed, scalars: ScalarLog, *,
                 port: int, rate_hz: float, host: str = "127.0.0.1", paced: bool = True):
        self.controls, self.exchange, self.feed, self.scalars = controls, exchange, feed, scalars
        self.period_s = 1.0 / rate_hz
        self.paced = paced
        """Hold each loop of the streaming thread to ``period_s``; not when the frames arrive already
        paced (``remote``: pacing twice, at one rate, would drop a frame whenever they drift)."""
        self.server = viser.ViserServer(host=host, port=port, label="ambulo", verbose=False)
        self.server.scene.set_up_direction("+z")
        # flat lights, no shadows or image-based lighting: colours read as MuJoCo's, and a software
        # rasterizer (a headless browser, a remote desktop) keeps up
        self.server.scene.configure_environment_map(hdri=None)
        self.server.scene.configure_default_lights(enabled=True, cast_shadow=False)
        # without the environment map nothing lights a face turned from the default lights: an
        # apartment's walls drew black. A dim ambient term, as MuJoCo's headlight ambient does
        self.server.scene.add_light_ambient("/ambient", intensity=AMBIENT_INTENSITY)
        self.port = self.server.get_port()
        self.url = f"http://{host}:{self.port}"
        self.grid = GridScene(self.server)
        self.overlays: Overlays | None = None
        self.panel: Panel | None = None
        self._model: mujoco.MjModel | None = None
        self._info: ModelInfo | None = None
        self._roots: list[int] = []
        self._follow_body: int | None = None
        self._curves = CurvePanel(self.server, scalars)
        self.frames_sent = 0
        self.stream_cpu_s = 0.0
        """CPU time the streaming thread has used, s."""
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._stream, name="ambulo-viewer", daemon=True)
        self.server.on_client_connect(self._place_camera)
        self._thread.start()

    # -- what the simulation side asks -----------------------------------------------------------
    def wants_state(self) -> tuple[bool, bool]:
        """(frames must carry the watched world's state, and its per-world camera poses)."""
        overlays, info = self.overlays, self._info
        if overlays is None or not overlays.needs_state:
            return False, False
        return True, bool(info is not None and info.camera_sensors and overlays.camera.value)

    def set_model(self, model: mujoco.MjModel, info: ModelInfo) -> None:
        """The model's shapes, once per grid slot (``scene.GridScene``), and the panel's controls."""
        shapes = geom_shapes(model)
        spacing_m = scene_spacing_m(shapes, info.xpos_w, info.xmat_w.reshape(-1, 3, 3))
        self.grid.set_model(model, shapes, spacing_m)
        self.grid.layout(len(self.controls.worlds()))
        self._roots = root_bodies(model)
        self._model, self._info = model, info
        # the first robot (the root with the most bodies below it) is the one the camera follows
        self._follow_body = max(self._roots, key=lambda r: len(subtree(model, r)), default=None)
        if self.panel is None:
            self.panel = Panel(self.server, self.controls, root_names=[body_name(model, r) for r in self._roots],
                               follow=info.follow, show_command=info.has_command, show_return=info.show_return,
                               can_reset=info.can_reset, spacing_m=spacing_m)
            for root, box in zip(self._roots, self.panel.visible.values()):
                box.on_update(lambda _e, root=root, box=box: self.grid.set_visible(subtree(self._model, root),
                                                                                     box.value))
            self.overlays = Overlays(self.server, self.feed)
        robot = self._follow_body
        self.overlays.set_model(model, robot, [] if robot is None else subtree(model, robot))
        for client in self.server.get_clients().values():
            self._place_camera(client)

    def add_scalars(self, step: float, scalars: dict[str, float]) -> None:
        """Queue ``scalars`` for the curve panel at x = ``step`` (``WebViewer.add_scalars``)."""
        self.scalars.add(step, scalars)

    def show_speed(self, speed: float | None) -> None:
        """Show ``speed`` in the page's Speed field (its callback sets the controls' speed)."""
        if self.panel is None:
            self.controls.speed = speed
        else:
            self.panel.speed.value = speed_label(speed)

    def close(self) -> None:
        """Stop streaming and the server."""
        self._stop.set()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
        self.server.stop()

    # -- internals ---------------------------------------------------------------------------------
    def _place_camera(self, client: viser.ClientHandle) -> None:
        if self._info is None:
            return
        cam = self._info.camera
        self.server.initial_camera.fov = cam.fovy_rad
        self.server.initial_camera.position = cam.eye_w
        self.server.initial_camera.look_at = cam.target_w
        self.server.initial_camera.up = (0.0, 0.0, 1.0)
        client.camera.up_direction = (0.0, 0.0, 1.0)
        client.camera.fov = cam.fovy_rad
        client.camera.position = cam.eye_w
        client.camera.look_at = cam.target_w

    def _stream(self) -> None:
        """The streaming thread: ask for a frame, send it, at most once per ``period_s``."""
        try:
            self._stream_frames()
        finally:
            if self.overlays is not None:
                self.overlays.close()  # its camera renderer's GL context belongs to this thread

    def _stream_frames(self) -> None:
        sequence, next_readout, next_curves = 0, 0.0, 0.0
        ticks = Ticks(self.period_s)
        while not self._stop.is_set():
            started, cpu0 = time.perf_counter(), time.thread_time()
            if started >= next_curves:  # curves are fed by the caller, not the simulation: drawn even while paused
                next_curves = started + READOUT_PERIOD_S
                try:
                    self._curves.update()
                except Exception:
                    log.exception("web viewer: drawing the curves failed")
            self.exchange.request()
            sequence, frame = self.exchange.latest(sequence, timeout_s=self.period_s)
            if frame is not None and self._model is not None:
                try:
                    self._send(frame, readout=started >= next_readout)
                except Exception:  # a page gone mid-send must not end the stream
                    log.exception("web viewer: sending a frame failed")
                if started >= next_readout:
                    next_readout = started + READOUT_PERIOD_S
            self.stream_cpu_s += time.thread_time() - cpu0
            if self.paced:
                ticks.wait(self._stop)

    def _send(self, frame, readout: bool) -> None:
        time_s, xpos_w, xquat_w, extras = frame.numpy()
        feed_scans(extras, self.feed)
        if self.panel is not None:
            self.grid.layout(len(frame.worlds), self.panel.spacing_m())
        with self.server.atomic():
            self.grid.send(xpos_w, xquat_w)
        self.frames_sent += 1
        if self.overlays is not None:
            self.overlays.draw(frame.state_numpy(), time.perf_counter())
        if self.panel is not None and self.panel.follow.value and self._follow_body is not None:
            self._follow(xpos_w[0, self._follow_body])
        if readout and self.panel is not None:
            self._write_readout(frame, time_s, xpos_w, extras)

    def _follow(self, root_w: np.ndarray) -> None:
        """Keep the opening camera's offset from the robot. (Not the page's current offset: the page
        reports its camera back asynchronously, and an offset read from that lags our own moves, so
        the camera drifted away. Untick Follow to orbit freely.)"""
        cam = self._info.camera
        offset = np.asarray(cam.eye_w) - np.asarray(cam.target_w)
        for client in self.server.get_clients().values():
            with client.atomic():
                client.camera.look_at = root_w
                client.camera.position = root_w + offset

    def _write_readout(self, frame, time_s: float, xpos_w: np.ndarray, extras: dict) -> None:
        if int(self.panel.world.value) != frame.world:  # watch() from Python: the page shows it too
            self.panel.world.value = frame.world
        state = "paused" if frame.paused else "running"
        drawn = f" (+{len(frame.worlds) - 1} beside it)" if len(frame.worlds) > 1 else ""
        self.panel.status.content = (f"**t = {time_s:.2f} s** · {state} · world {frame.world} of "
                                     f"{self.controls.num_worlds}{drawn} · {self.frames_sent} frames sent")
        pos = xpos_w[0]
        rows = [f"- `{body_name(self._model, r)}` ({pos[r][0]:.3f}, {pos[r][1]:.3f}, {pos[r][2]:.3f}) m"
                for r in self._roots]
        if "command" in extras:
            c = extras["command"]
            rows.append(f"- command ({c[0]:.2f} m/s, {c[1]:.2f} m/s, {c[2]:.2f} rad/s)")
        if "episode_return" in extras:
            rows.append(f"- episode return {float(extras['episode_return'][0]):.3f}")
            self.panel.show_return(time_s, float(extras["episode_return"][0]))
        self.panel.readout.content = "\n".join(rows)
