"""``WebViewer``: a viser server on 127.0.0.1 that shows one world of a running simulation.

It joins the watched ``Simulation`` as a component (``ambulo.core.Component``): after every step
its ``update`` applies the page's requests (pause blocks the simulation thread there, a reset,
the teleoperated command) and, only when the streaming thread asked for a frame, copies one
world's body poses (``frames.FrameExchange``). The streaming thread sends those poses to the page
at ``rate_hz`` at most, as one atomic update of the moving bodies' frames; the shapes were sent
once, when the model was compiled (``initialize``).
"""

from __future__ import annotations

import logging
import threading
import time

import mujoco
import numpy as np
import viser

from ..engine import STATE_FIELDS
from ..sensors.camera import Camera as CameraSensor
from .camera import CameraPose
from .controls import Controls
from .curves import CurvePanel, ScalarLog
from .feed import OverlayFeed
from .feed_api import FeedApi
from .frames import FrameExchange, copy_world
from .geometry import body_name, geom_shapes, root_bodies, subtree
from .gui import Panel
from .layout import scene_spacing_m
from .overlays import Overlays
from .scene import GridScene

log = logging.getLogger(__name__)

COMPONENT_NAME = "ambulo.viewer"
READOUT_PERIOD_S = 0.2
"""s between updates of the panel's text and curve (text at 30 Hz only costs bandwidth)."""
AMBIENT_INTENSITY = 0.6
"""Ambient light of the page (three.js units; 0.6 keeps a wall turned from the lights a mid grey)."""
STATE_ROWS = tuple(f for f in STATE_FIELDS if f != "time")
"""The watched world's state an overlay recomputes contacts and balance from (``physics_overlay``)."""


class WebViewer(FeedApi):
    """A browser view of ``target`` (``targets.WorldTarget`` or ``EnvTarget``).

    Args:
      target: what to watch.
      port: TCP port on 127.0.0.1 (viser moves to the next free one if taken: read ``port``).
      rate_hz: most frames per second streamed to the page.
      grid: worlds drawn side by side from the start (the page's "Worlds drawn" changes it).
    """

    def __init__(self, target, *, port: int = 8080, rate_hz: float = 30.0, host: str = "127.0.0.1",
                 grid: int = 1):
        if rate_hz <= 0:
            raise ValueError(f"rate_hz is {rate_hz}: pass frames per second, e.g. 30")
        self.name = COMPONENT_NAME
        self.target = target
        self.period_s = 1.0 / rate_hz
        self.controls = Controls(target.num_worlds, speed=target.default_speed)
        self.controls.show(grid)
        self._pace = _Pace()
        self.exchange = FrameExchange()
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
        self._model: mujoco.MjModel | None = None
        self._camera_sensors = False
        self._engine = None
        self.grid = GridScene(self.server)
        self.feed = OverlayFeed()
        self.overlays: Overlays | None = None
        self._roots: list[int] = []
        self._follow_body: int | None = None
        self._camera: CameraPose | None = None
        self.panel: Panel | None = None
        self.scalars = ScalarLog()
        self._curves = CurvePanel(self.server, self.scalars)
        self.frames_sent = 0
        self.stream_cpu_s = 0.0
        """CPU time the streaming thread has used, s (what the viewer takes from the machine)."""
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._stream, name="ambulo-viewer", daemon=True)
        self.server.on_client_connect(self._place_camera)
        sim = target.sim
        if COMPONENT_NAME in sim.components:
            raise ValueError("this simulation already has a web viewer; close it first (viewer.close())")
        sim.add(self)
        if sim.engine is not None:
            self.initialize(sim.engine)
        self._thread.start()

    # -- the Component protocol (simulation thread) ----------------------------------------------
    def build(self, spec: mujoco.MjSpec) -> None:
        """Nothing to add to the scene: the viewer only reads poses."""

    def initialize(self, engine) -> None:
        """Send the compiled model's shapes (again only if the model changed) and a first frame."""
        self._engine = engine
        if engine.model is not self._model:
            self._send_model(engine.model)
        self.exchange.publish(self._copy())

    def update(self, dt_s: float) -> None:
        controls, target = self.controls, self.target
        world = controls.world
        if controls.take_reset():
            target.reset_world(world)
        command = controls.command()
        if command is not None:
            target.apply_command(world, command)
        if controls.paused:
            self.exchange.publish(self._copy(paused=True))
            controls.wait_while_paused(self._on_pause_wake)
            self._pace.restart()
        self._pace.hold(dt_s, controls.speed)
        if self.exchange.wanted():
            self.exchange.publish(self._copy())

    def reset(self, world_ids=None) -> None:
        """Nothing of the viewer's is per world."""

    # -- what scripts read ------------------------------------------------------------------------
    def velocity_command(self, default) -> np.ndarray:
        """The page's (vx m/s, vy m/s, yaw rate rad/s) while it teleoperates, else ``default``."""
        command = self.controls.command()
        return np.asarray(default, dtype=float) if command is None else command

    def add_scalars(self, step: int, scalars: dict[str, float]) -> None:
        """Plot ``scalars`` ({name: value}, e.g. mean reward, episode length, a task's criteria) at
        x = ``step`` (a training iteration), one curve per name beside the scene. Safe from any
        thread and cheap: it queues the values; the streaming thread draws them (5 times a second)."""
        self.scalars.add(step, scalars)

    def watch(self, world: int) -> None:
        """Show world ``world`` (as the page's World field does)."""
        self.controls.watch(world)

    def close(self) -> None:
        """Stop streaming, free a paused simulation, leave the simulation and stop the server."""
        if self._stop.is_set():
            return
        self._stop.set()
        self.controls.close()
        self.target.sim.components.pop(COMPONENT_NAME, None)
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
        self.server.stop()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- internals ---------------------------------------------------------------------------------
    def _on_pause_wake(self) -> None:
        if self.controls.take_reset():
            self.target.reset_world(self.controls.world)
        if self.exchange.wanted():
            self.exchange.publish(self._copy(paused=True))

    def _copy(self, paused: bool = False):
        e, worlds = self._engine, self.controls.worlds()
        state = None
        if self.overlays is not None and self.overlays.needs_state:
            state = {f: e.field(f) for f in STATE_ROWS}
            if self._camera_sensors and self.overlays.camera.value:  # where the sensors put their cameras
                state.update({f"model.{f}": e.model_field(f) for f in ("cam_pos", "cam_quat")})
        frame = copy_world(worlds, e.field("time"), e.field("xpos"), e.field("xquat"),
                           self.target.extras(worlds[0]), state)
        frame.paused = paused
        return frame

    def _send_model(self, model: mujoco.MjModel) -> None:
        """The model's shapes, once per grid slot (``scene.GridScene``), and the panel's controls."""
        shapes = geom_shapes(model)
        e = self._engine
        spacing_m = scene_spacing_m(shapes, e.field("xpos")[0].cpu().numpy(),
                                    e.field("xmat")[0].cpu().numpy().reshape(-1, 3, 3))
        self.grid.set_model(model, shapes, spacing_m)
        # camera sensors pose their model cameras per world (``engine.model_field``); without one the
        # shared model's poses hold, and the viewer must not make those fields per world itself
        self._camera_sensors = any(isinstance(c, CameraSensor) or isinstance(getattr(c, "sensor", None), CameraSensor)
                                   for c in self.target.sim.components.values())  # (Isaac-style ones wrap it)
        self.grid.layout(len(self.controls.worlds()))
        self._roots = root_bodies(model)
        self._model = model
        self._camera = self.target.camera(model)
        # the first robot (the root with the most bodies below it) is the one the camera follows
        self._follow_body = max(self._roots, key=lambda r: len(subtree(model, r)), default=None)
        if self.panel is None:
            self.panel = Panel(self.server, self.controls, root_names=[body_name(model, r) for r in self._roots],
                               follow=self.target.follow_default, show_command=self.target.has_command,
                               show_return=hasattr(self.target, "env"), can_reset=self.target.can_reset,
                               spacing_m=spacing_m)
            for root, box in zip(self._roots, self.panel.visible.values()):
                box.on_update(lambda _e, root=root, box=box: self.grid.set_visible(subtree(self._model, root),
                                                                                     box.value))
            self.overlays = Overlays(self.server, self.feed)
        robot = self._follow_body
        self.overlays.set_model(model, robot, [] if robot is None else subtree(model, robot))
        for client in self.server.get_clients().values():
            self._place_camera(client)

    def _place_camera(self, client: viser.ClientHandle) -> None:
        if self._camera is None:
            return
        cam = self._camera
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
            self._stop.wait(max(0.0, self.period_s - (time.perf_counter() - started)))

    def _send(self, frame, readout: bool) -> None:
        time_s, xpos_w, xquat_w, extras = frame.numpy()
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
        offset = np.asarray(self._camera.eye_w) - np.asarray(self._camera.target_w)
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


class _Pace:
    """Holds the simulation to ``speed`` simulated seconds per wall second (sleeping in its thread)."""

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
