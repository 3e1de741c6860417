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
from viser import _messages

from .camera import CameraPose
from .controls import Controls
from .curves import CurvePanel, ScalarLog
from .frames import FrameExchange, copy_world
from .geometry import body_name, geom_shapes, root_bodies, static_bodies, subtree
from .gui import Panel

log = logging.getLogger(__name__)

COMPONENT_NAME = "ambulo.viewer"
READOUT_PERIOD_S = 0.2
"""s between updates of the panel's text and curve (text at 30 Hz only costs bandwidth)."""


class WebViewer:
    """A browser view of ``target`` (``targets.WorldTarget`` or ``EnvTarget``).

    Args:
      target: what to watch.
      port: TCP port on 127.0.0.1 (viser moves to the next free one if taken: read ``port``).
      rate_hz: most frames per second streamed to the page.
    """

    def __init__(self, target, *, port: int = 8080, rate_hz: float = 30.0, host: str = "127.0.0.1"):
        if rate_hz <= 0:
            raise ValueError(f"rate_hz is {rate_hz}: pass frames per second, e.g. 30")
        self.name = COMPONENT_NAME
        self.target = target
        self.period_s = 1.0 / rate_hz
        self.controls = Controls(target.num_worlds, speed=target.default_speed)
        self._pace = _Pace()
        self.exchange = FrameExchange()
        self.server = viser.ViserServer(host=host, port=port, label="ambulo", verbose=False)
        self.server.scene.set_up_direction("+z")
        # flat lights, no shadows or image-based lighting: colours read as MuJoCo's, and a software
        # rasterizer (a headless browser, a remote desktop) keeps up
        self.server.scene.configure_environment_map(hdri=None)
        self.server.scene.configure_default_lights(enabled=True, cast_shadow=False)
        self.port = self.server.get_port()
        self.url = f"http://{host}:{self.port}"
        self._model: mujoco.MjModel | None = None
        self._engine = None
        self._frames: dict[int, viser.FrameHandle] = {}
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
        e, world = self._engine, self.controls.world
        frame = copy_world(world, e.field("time"), e.field("xpos"), e.field("xquat"), self.target.extras(world))
        frame.paused = paused
        return frame

    def _send_model(self, model: mujoco.MjModel) -> None:
        scene = self.server.scene
        for handle in self._frames.values():
            handle.remove()
        self._frames.clear()
        static = static_bodies(model)
        for shape in geom_shapes(model):
            b = shape.body_id
            if b not in self._frames:
                self._frames[b] = scene.add_frame(f"/b{b}", show_axes=False)
            rgb = tuple(int(round(255 * c)) for c in shape.rgba[:3])
            opacity = None if shape.rgba[3] >= 1.0 else shape.rgba[3]
            scene.add_mesh_simple(f"/b{b}/g{shape.geom_id}", shape.vertices_b, shape.faces, color=rgb,
                                  opacity=opacity, cast_shadow=not shape.is_plane, receive_shadow=True)
            if shape.is_plane:
                half = float(np.abs(shape.vertices_b[:, :2]).max())
                scene.add_grid(f"/b{b}/grid{shape.geom_id}", width=2 * half, height=2 * half,
                               position=tuple(shape.vertices_b[:, :3].mean(axis=0) + [0, 0, 1e-3]),
                               cell_size=0.5, section_size=1.0, plane_opacity=0.0)
        self._static = static
        self._roots = root_bodies(model)
        self._model = model
        self._camera = self.target.camera(model)
        # the first robot (the root with the most bodies below it) is the one the camera follows
        self._follow_body = max(self._roots, key=lambda r: len(subtree(model, r)), default=None)
        self._sent_static = False
        if self.panel is None:
            self.panel = Panel(self.server, self.controls, root_names=[body_name(model, r) for r in self._roots],
                               follow=self.target.follow_default, show_command=self.target.has_command,
                               show_return=hasattr(self.target, "env"), can_reset=self.target.can_reset)
            for root, box in zip(self._roots, self.panel.visible.values()):
                box.on_update(lambda _e, root=root, box=box: self._show_subtree(root, box.value))
        for client in self.server.get_clients().values():
            self._place_camera(client)

    def _show_subtree(self, root: int, visible: bool) -> None:
        for b in subtree(self._model, root):
            if b in self._frames:
                self._frames[b].visible = visible

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
        with self.server.atomic():
            moving = [b for b in self._frames if not (self._static[b] and self._sent_static)]
            _queue_poses([self._frames[b] for b in moving], xpos_w[moving].tolist(), xquat_w[moving].tolist())
        self._sent_static = True
        self.frames_sent += 1
        if self.panel is not None and self.panel.follow.value and self._follow_body is not None:
            self._follow(xpos_w[self._follow_body])
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
        self.panel.status.content = (f"**t = {time_s:.2f} s** · {state} · world {frame.world} of "
                                     f"{self.controls.num_worlds} · {self.frames_sent} frames sent")
        rows = [f"- `{body_name(self._model, r)}` ({xpos_w[r][0]:.3f}, {xpos_w[r][1]:.3f}, {xpos_w[r][2]:.3f}) m"
                for r in self._roots]
        if "command" in extras:
            c = extras["command"]
            rows.append(f"- command ({c[0]:.2f} m/s, {c[1]:.2f} m/s, {c[2]:.2f} rad/s)")
        if "episode_return" in extras:
            rows.append(f"- episode return {float(extras['episode_return'][0]):.3f}")
            self.panel.show_return(time_s, float(extras["episode_return"][0]))
        self.panel.readout.content = "\n".join(rows)


def _queue_poses(handles: list, positions: list, quats_wxyz: list) -> None:
    """Queue new poses of scene nodes: what ``handle.position = ...; handle.wxyz = ...`` does in
    viser 1.1.1 (``_scene_handles._set_pose_vector``) without its per-value cast and ``np.allclose``
    test, a tenth of the streaming thread's time per frame (0.3 ms instead of 3.4 ms for 19
    bodies, measured). Private API: viser is pinned in pyproject.toml, and the page test
    (tests/viewer/test_viewer_browser.py) fails if the page stops following the poses."""
    for handle, position, wxyz in zip(handles, positions, quats_wxyz):
        impl = handle._impl
        impl.position[:] = position
        impl.wxyz[:] = wxyz
        impl.api._queue_scene_message(_messages.SetPositionMessage(impl.name, tuple(position)))
        impl.api._queue_scene_message(_messages.SetOrientationMessage(impl.name, tuple(wxyz)))


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
