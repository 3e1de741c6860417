"""``WebViewer``: the simulation side of the web viewer, one world of a running simulation in a browser.

It joins the watched ``Simulation`` as a component (``ambulo.core.Component``): after every step
its ``update`` applies the page's requests (pause blocks the simulation thread there, a reset,
the teleoperated command) and, only when the stream asked for a frame, copies the drawn worlds'
body poses (``frames.FrameExchange``). Everything else happens away from the simulation thread.

By default the page's server (viser: message building, serialization, the websocket) runs in a
process of its own (``remote``): in the watched process it would hold the GIL against a training
loop that is itself Python-bound (kernel launches), and on the H200 the viewer cost 16 % of the
env-steps/s of ``ambulo train`` while its streaming thread used only 2 % of the CPU. What stays
here is a thread that asks for a frame at the capped rate and writes its few hundred floats to a
pipe. ``process=False`` keeps the server in this process (``page.PageServer``, inspected by tests).
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..engine import STATE_FIELDS
from ..sensors.camera import Camera as CameraSensor
from .controls import Controls
from .curves import ScalarLog
from .feed import OverlayFeed
from .feed_api import FeedApi
from .frames import FrameExchange, copy_world
from .pace import Pace
from .page import ModelInfo, PageServer
from .remote import PageProcess
from .sensor_feeds import SensorFeeds

COMPONENT_NAME = "ambulo.viewer"
STATE_ROWS = tuple(f for f in STATE_FIELDS if f != "time")
"""The watched world's state an overlay recomputes contacts and balance from (``physics_overlay``)."""


class WebViewer(FeedApi):
    """A browser view of ``target`` (``targets.WorldTarget`` or ``EnvTarget``).

    Args:
      target: what to watch.
      port: TCP port on 127.0.0.1 (viser moves to the next free one if taken: read ``port``).
      rate_hz: most frames per second streamed to the page.
      grid: worlds drawn side by side from the start (the page's "Worlds drawn" changes it).
      process: serve the page from a process of its own (default), else from threads of this one.
    """

    def __init__(self, target, *, port: int = 8080, rate_hz: float = 30.0, host: str = "127.0.0.1",
                 grid: int = 1, process: bool = True):
        if rate_hz <= 0:
            raise ValueError(f"rate_hz is {rate_hz}: pass frames per second, e.g. 30")
        sim = target.sim
        if COMPONENT_NAME in sim.components:
            raise ValueError("this simulation already has a web viewer; close it first (viewer.close())")
        self.name = COMPONENT_NAME
        self.target = target
        self.controls = Controls(target.num_worlds, speed=target.default_speed)
        self.controls.show(grid)
        self._pace = Pace()
        self.exchange = FrameExchange()
        self._engine = None
        self._model: mujoco.MjModel | None = None
        self._closed = False
        self.page: PageServer | None = None
        """The in-process server (``process=False``; tests inspect its widgets), else None."""
        self.link: PageProcess | None = None
        """The link to the server's own process (the default), else None."""
        if process:
            self.link = PageProcess(self.controls, self.exchange, port=port, rate_hz=rate_hz, host=host)
            self.feed: OverlayFeed = self.link.feed
        else:
            self.feed = OverlayFeed()
            self.page = PageServer(self.controls, self.exchange, self.feed, ScalarLog(), port=port,
                                   rate_hz=rate_hz, host=host)
        self.server: PageServer | PageProcess = self.link or self.page
        """Whichever of the two serves the page: both answer the calls below the same way."""
        self.port = self.server.port
        self.url = f"http://{host}:{self.port}"
        self.sensor_feeds = SensorFeeds()
        sim.add(self)
        if sim.engine is not None:
            self.initialize(sim.engine)

    # -- the Component protocol (simulation thread) ----------------------------------------------
    def build(self, spec: mujoco.MjSpec) -> None:
        """Nothing to add to the scene: the viewer only reads poses."""

    def initialize(self, engine) -> None:
        """Send the compiled model's shapes (again only if the model changed) and a first frame."""
        self._engine = engine
        if engine.model is not self._model:
            self._model = engine.model
            info = self._model_info(engine)
            self.server.set_model(engine.model, info)
            self.sensor_feeds.set_sensors(self.target.sim.components.values())
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
    @property
    def frames_sent(self) -> int:
        """Pose frames handed to the page's server so far."""
        return self.server.frames_sent

    @property
    def stream_cpu_s(self) -> float:
        """CPU time this process's streaming thread has used, s (what the viewer takes from the watched
        process; with ``process``, the server's own process's time is ``link.server_cpu_s()``)."""
        return self.server.stream_cpu_s

    def velocity_command(self, default) -> np.ndarray:
        """The page's (vx m/s, vy m/s, yaw rate rad/s) while it teleoperates, else ``default``."""
        command = self.controls.command()
        return np.asarray(default, dtype=float) if command is None else command

    def add_scalars(self, step: int, scalars: dict[str, float]) -> None:
        """Plot ``scalars`` ({name: value}, e.g. mean reward, episode length, a task's criteria) at
        x = ``step`` (a training iteration), one curve per name beside the scene. Safe from any
        thread and cheap: it queues the values; the streaming side draws them (5 times a second)."""
        self.server.add_scalars(step, scalars)

    def watch(self, world: int) -> None:
        """Show world ``world`` (as the page's World field does)."""
        self.controls.watch(world)

    def set_speed(self, speed: float | None) -> None:
        """Hold the simulation to ``speed`` simulated s per wall s (None: as fast as it runs), as the
        page's Speed field does (the field shows it)."""
        self.controls.speed = speed
        self.server.show_speed(speed)

    def close(self) -> None:
        """Stop streaming, free a paused simulation, leave the simulation and stop the server."""
        if self._closed:
            return
        self._closed = True
        self.controls.close()
        self.target.sim.components.pop(COMPONENT_NAME, None)
        self.server.close()

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
        with_state, with_cameras = self.server.wants_state()
        state = None
        if with_state:
            state = {f: e.field(f) for f in STATE_ROWS}
            if with_cameras:  # where the sensors put their cameras
                state.update({f"model.{f}": e.model_field(f) for f in ("cam_pos", "cam_quat")})
        extras = {**self.target.extras(worlds[0]), **self.sensor_feeds.rows(worlds[0])}
        frame = copy_world(worlds, e.field("time"), e.field("xpos"), e.field("xquat"), extras, state)
        frame.paused = paused
        return frame

    def _model_info(self, engine) -> ModelInfo:
        # camera sensors pose their model cameras per world (``engine.model_field``); without one the
        # shared model's poses hold, and the viewer must not make those fields per world itself
        camera_sensors = any(isinstance(c, CameraSensor) or isinstance(getattr(c, "sensor", None), CameraSensor)
                             for c in self.target.sim.components.values())  # (Isaac-style ones wrap it)
        return ModelInfo(xpos_w=engine.field("xpos")[0].cpu().numpy().copy(),
                         xmat_w=engine.field("xmat")[0].cpu().numpy().copy(),
                         camera=self.target.camera(engine.model), follow=self.target.follow_default,
                         has_command=self.target.has_command, show_return=hasattr(self.target, "env"),
                         can_reset=self.target.can_reset, camera_sensors=camera_sensors)
