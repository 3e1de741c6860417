"""The page's server in a process of its own, fed through a pipe (``WebViewer(process=True)``).

Parent (the watched process), ``PageProcess``: a pump thread asks the simulation for a frame at
the capped rate (``FrameExchange``, as the in-process streaming thread does), waits for its copy
off the device and writes its host arrays to the pipe: a few hundred floats, tens of microseconds
of this process's time per frame. A reader thread applies what the page asks (pause, step, reset,
the watched world, the command, the speed) to the simulation's ``Controls``. Features' overlays
(``show_*``) and curves (``add_scalars``) go down the same pipe from whatever thread calls them;
a writer thread does the writing (``_Outbox``), so no caller waits on the pipe.

Child (``serve``): the ``page.PageServer`` (viser, its
event loop and the streaming thread), with a ``Controls`` whose writes travel back up the pipe. It
runs in a new executable and session. It ignores Ctrl-C (the watched process
handles it and closes the viewer) and stops when the pipe closes, so a killed parent leaves no
server behind.
"""

from __future__ import annotations

import logging
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections import OrderedDict
from multiprocessing.connection import Connection

import numpy as np

from .controls import Controls
from .feed import OverlayFeed
from .frames import Frame, FrameExchange
from .pace import Ticks

log = logging.getLogger(__name__)

START_LIMIT_S = 120.0
"""s the child may take to import viser and open its port (a loaded machine is slow)."""
CLOSE_LIMIT_S = 5.0
FORWARDED = ("set_paused", "step_once", "request_reset", "watch", "show", "set_command", "release_command")
"""The ``Controls`` writes the page makes, applied to the simulation's controls by name."""


class _Sender:
    """``conn.send`` from several threads (a Connection is not thread-safe); quiet once closed."""

    def __init__(self, conn: Connection):
        self.conn, self._lock, self.broken = conn, threading.Lock(), False

    def __call__(self, message) -> None:
        if self.broken:
            return
        try:
            with self._lock:
                self.conn.send(message)
        except (OSError, EOFError, ValueError):  # the other side is gone
            self.broken = True


class _Outbox:
    """Messages to the page's process, written by a thread of their own: a caller (the simulation
    thread showing a map, the pump with a frame) never waits on the pipe, even while the server is
    busy building an apartment's meshes. A message with a ``key`` replaces an unsent one of the
    same key (only the newest frame, or layer, matters) and goes after those queued since."""

    def __init__(self, send: _Sender):
        self._send, self._ready = send, threading.Condition()
        self._pending: OrderedDict[object, tuple] = OrderedDict()
        self._count, self._closed = 0, False
        self._thread = threading.Thread(target=self._write, name="ambulo-viewer-pipe", daemon=True)
        self._thread.start()

    def __call__(self, message: tuple, key=None) -> None:
        with self._ready:
            self._count += 1
            key = ("once", self._count) if key is None else key
            self._pending.pop(key, None)
            self._pending[key] = message
            self._ready.notify()

    def close(self) -> None:
        """Send what is queued, then stop."""
        with self._ready:
            self._closed = True
            self._ready.notify()
        self._thread.join(timeout=CLOSE_LIMIT_S)

    def _write(self) -> None:
        while True:
            with self._ready:
                self._ready.wait_for(lambda: self._pending or self._closed)
                if not self._pending:
                    return
                _, message = self._pending.popitem(last=False)
            self._send(message)


class _ForwardingFeed(OverlayFeed):
    """The overlay feed of the watched process: keeps the latest value per layer (``get``) and sends it."""

    def __init__(self, outbox: _Outbox):
        super().__init__()
        self._outbox = outbox

    def put(self, layer: str, value) -> None:
        super().put(layer, value)
        self._outbox(("feed", layer, value), key=("feed", layer))


class PageProcess:
    """The parent's end (see the module): starts the child and keeps the page fed."""

    def __init__(self, controls: Controls, exchange: FrameExchange, *, port: int, rate_hz: float, host: str):
        self.controls, self.exchange, self.period_s = controls, exchange, 1.0 / rate_hz
        mine, theirs = socket.socketpair()
        # a new executable: a fork would copy CUDA and thread state, multiprocessing's spawn re-imports the
        # user's script; a new session: Ctrl-C in the terminal goes to the watched process only
        self.process = subprocess.Popen(
            [sys.executable, "-c", f"from ambulo.viewer.remote import serve; serve({theirs.fileno()})"],
            pass_fds=(theirs.fileno(),), start_new_session=True,
            stdout=subprocess.DEVNULL)  # viser's banner; the URL is ours to print (errors go to stderr)
        theirs.close()
        self.conn = Connection(mine.detach())
        self.send = _Sender(self.conn)
        self.send(("hello", {"host": host, "port": port, "rate_hz": rate_hz, "num_worlds": controls.num_worlds,
                             "speed": controls.speed, "shown": len(controls.worlds())}))
        try:
            ready = self.conn.recv() if self.conn.poll(START_LIMIT_S) else None
        except (EOFError, OSError):
            ready = None
        if not (isinstance(ready, tuple) and ready[0] == "ready"):
            self.conn.close()  # the child, if it hangs, sees its pipe close
            self._end_child()
            raise RuntimeError(f"the web viewer's server process did not start (exit code {self.process.poll()}); "
                               "its error is printed above")
        self.port = int(ready[1])
        self.outbox = _Outbox(self.send)
        self.feed = _ForwardingFeed(self.outbox)
        self.frames_sent = 0
        self.stream_cpu_s = 0.0
        """CPU time of the pump thread, s (this process's share of the viewer)."""
        self._wants = (False, False)
        self._stop = threading.Event()
        self._reader = threading.Thread(target=self._read, name="ambulo-viewer-controls", daemon=True)
        self._pump = threading.Thread(target=self._stream, name="ambulo-viewer", daemon=True)
        self._reader.start()
        self._pump.start()

    def wants_state(self) -> tuple[bool, bool]:
        return self._wants

    def set_model(self, model, info) -> None:
        self.outbox(("model", model, info))

    def add_scalars(self, step: float, scalars: dict[str, float]) -> None:
        self.outbox(("scalars", float(step), {str(k): float(v) for k, v in scalars.items()}))

    def show_speed(self, speed: float | None) -> None:
        self.outbox(("speed", speed), key="speed")

    def server_cpu_s(self) -> float:
        """CPU time the server's process has used so far, s (Linux ``/proc``; 0 elsewhere)."""
        try:
            with open(f"/proc/{self.process.pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
        except (OSError, IndexError, ValueError):
            return 0.0

    def close(self) -> None:
        self._stop.set()
        if self._pump is not threading.current_thread():
            self._pump.join(timeout=CLOSE_LIMIT_S)
        self.outbox(("close",))
        self.outbox.close()
        self._end_child()
        self.conn.close()
        self._reader.join(timeout=CLOSE_LIMIT_S)

    def _end_child(self) -> None:
        try:
            self.process.wait(timeout=CLOSE_LIMIT_S)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()

    def _stream(self) -> None:
        """Ask for a frame, send it, at most once per ``period_s`` (the page's server draws each as it comes)."""
        sequence, ticks = 0, Ticks(self.period_s)
        while not self._stop.is_set():
            cpu0 = time.thread_time()
            self.exchange.request()
            sequence, frame = self.exchange.latest(sequence, timeout_s=self.period_s)
            if frame is not None:
                self.outbox(("frame", host_frame(frame)), key="frame")
                self.frames_sent += 1
            self.stream_cpu_s += time.thread_time() - cpu0
            if self.send.broken:
                log.warning("web viewer: the page's server process ended; the simulation goes on unwatched")
                return
            ticks.wait(self._stop)

    def _read(self) -> None:
        while True:
            try:
                message = self.conn.recv()
            except (EOFError, OSError):
                return
            kind = message[0]
            if kind == "controls" and message[1] in FORWARDED:
                getattr(self.controls, message[1])(*message[2])
            elif kind == "speed":
                self.controls.speed = message[1]
            elif kind == "wants":
                self._wants = message[1]


def host_frame(frame: Frame) -> tuple:
    """A frame as picklable host arrays (waits for its copy off the device: the pump's thread, not the simulation's)."""
    time_s, xpos_w, xquat_w, extras = frame.numpy()
    return frame.worlds, time_s, xpos_w, xquat_w, extras, frame.state_numpy(), frame.paused


def frame_of(host: tuple) -> Frame:
    worlds, time_s, xpos_w, xquat_w, extras, state, paused = host
    return Frame(worlds=list(worlds), time_s=np.float64(time_s), xpos_w=xpos_w, xquat_w=xquat_w, extras=extras,
                 state=state, paused=paused)


# -- the child --------------------------------------------------------------------------------------
class _PageControls(Controls):
    """The page's ``Controls`` in the server's process: kept here for the page and sent to the simulation's."""

    def __init__(self, send: _Sender, num_worlds: int, speed: float | None, shown: int):
        self._send = None
        super().__init__(num_worlds, speed=speed)
        super().show(shown)
        self._send = send

    @property
    def speed(self) -> float | None:
        return self._speed

    @speed.setter
    def speed(self, speed: float | None) -> None:
        self._speed = speed
        if self._send is not None:
            self._send(("speed", speed))


def _forwarding(name: str):
    def method(self, *args):
        result = getattr(Controls, name)(self, *args)
        self._send(("controls", name, tuple(np.asarray(a).tolist() if isinstance(a, np.ndarray) else a
                                            for a in args)))
        return result

    method.__name__ = name
    return method


for _name in FORWARDED:
    setattr(_PageControls, _name, _forwarding(_name))


class _PageExchange(FrameExchange):
    """Frames as they arrive from the pipe; the streaming thread's requests tell the simulation side
    which state the overlays need (the rate is the simulation side's pump's)."""

    def __init__(self, send: _Sender):
        super().__init__()
        self._send, self.page, self._wants = send, None, (False, False)

    def request(self) -> None:
        wants = self.page.wants_state() if self.page is not None else (False, False)
        if wants != self._wants:
            self._wants = wants
            self._send(("wants", wants))


def serve(fd: int) -> None:
    """The child's main: a ``PageServer`` drawing what comes down the pipe, until it closes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the watched process's to handle: it closes us
    from .curves import ScalarLog
    from .page import PageServer

    conn = Connection(fd)
    send = _Sender(conn)
    try:
        _, hello = conn.recv()
    except (EOFError, OSError):
        return
    controls = _PageControls(send, hello["num_worlds"], hello["speed"], hello["shown"])
    exchange, feed, scalars = _PageExchange(send), OverlayFeed(), ScalarLog()
    page = PageServer(controls, exchange, feed, scalars, port=hello["port"], rate_hz=hello["rate_hz"],
                      host=hello["host"], paced=False)  # the pump paces the frames
    exchange.page = page
    send(("ready", page.port))
    try:
        while True:
            message = conn.recv()
            kind = message[0]
            if kind == "frame":
                exchange.publish(frame_of(message[1]))
            elif kind == "model":
                page.set_model(message[1], message[2])
            elif kind == "feed":
                feed.put(message[1], message[2])
            elif kind == "scalars":
                scalars.add(message[1], message[2])
            elif kind == "speed":
                page.show_speed(message[1])
            elif kind == "close":
                break
    except (EOFError, OSError):  # the watched process is gone
        pass
    finally:
        page.close()

