"""The hand-over of poses from the simulation thread to the viewer's streaming thread.

The simulation never waits for the browser: the streaming thread asks for a frame (``request``)
at its capped rate, and the simulation, after its next step, copies the drawn worlds' body poses (a
few hundred floats each) into a new ``Frame`` and swaps it in under a lock held only for the swap.
Between requests a step costs one ``Event.is_set`` test. On a GPU the copy is asynchronous
(pinned memory, a CUDA event the streaming thread waits on), so the simulation thread never
synchronizes the device for the viewer.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import numpy as np
import torch


@dataclass
class Frame:
    """The drawn worlds' state at one instant, as the streaming thread reads it: CPU tensors (pinned,
    copied off a GPU) in the watched process, host arrays in the page's own (``remote``).

    Attributes:
      worlds: the world indices drawn (the watched one first; more for a grid).
      time_s: the watched world's simulated time, s.
      xpos_w: (K, nbody, 3) body positions of each drawn world, world frame, m.
      xquat_w: (K, nbody, 4) body orientations (w, x, y, z), world frame.
      extras: named (k,) values of the watched world (the env's command, its episode return), or empty.
      state: the watched world's MjData state rows (qpos, qvel, ctrl, ...) when an overlay needs to
        recompute it on the viewer thread (contacts, balance), else empty.
    """

    worlds: list[int]
    time_s: torch.Tensor | np.ndarray
    xpos_w: torch.Tensor | np.ndarray
    xquat_w: torch.Tensor | np.ndarray
    extras: dict[str, torch.Tensor | np.ndarray]
    state: dict[str, torch.Tensor | np.ndarray] = field(default_factory=dict)
    ready: torch.cuda.Event | None = None
    paused: bool = False
    """Copied while the simulation thread was held by the page's pause (the state is frozen)."""

    @property
    def world(self) -> int:
        """The watched world."""
        return self.worlds[0]

    def numpy(self) -> tuple[float, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """(time_s, xpos_w, xquat_w, extras) as host values; waits for a GPU copy to land."""
        if self.ready is not None:
            self.ready.synchronize()
        return (float(self.time_s), np.asarray(self.xpos_w), np.asarray(self.xquat_w),
                {k: np.asarray(v) for k, v in self.extras.items()})

    def state_numpy(self) -> dict[str, np.ndarray]:
        """The watched world's copied state rows as host arrays (after ``numpy``)."""
        return {k: np.asarray(v) for k, v in self.state.items()}


def copy_world(worlds, time_s: torch.Tensor, xpos_w: torch.Tensor, xquat_w: torch.Tensor,
               extras: dict[str, torch.Tensor], state: dict[str, torch.Tensor] | None = None) -> Frame:
    """A ``Frame`` of rows ``worlds`` (an index or a list, the watched world first) of the (N, ...)
    engine tensors, of ``extras`` (the watched world's values already) and of ``state`` ((N, ...)
    fields whose watched row is copied), copied off the device without a sync."""
    worlds = [int(worlds)] if isinstance(worlds, (int, np.integer)) else [int(w) for w in worlds]
    first = worlds[0]
    index = _world_index(tuple(worlds), xpos_w.device)
    rows = {"time": time_s[first], "xpos": xpos_w[index], "xquat": xquat_w[index]}
    rows.update({f"x.{k}": v for k, v in extras.items()})
    rows.update({f"s.{k}": v[first] for k, v in (state or {}).items()})
    device = xpos_w.device
    if device.type == "cuda":
        host = {k: torch.empty(v.shape, dtype=v.dtype, pin_memory=True) for k, v in rows.items()}
        for k, v in rows.items():
            host[k].copy_(v, non_blocking=True)
        ready = torch.cuda.Event()
        ready.record(torch.cuda.current_stream(device))
    else:
        host, ready = {k: v.detach().clone() for k, v in rows.items()}, None
    return Frame(worlds=worlds, time_s=host["time"], xpos_w=host["xpos"], xquat_w=host["xquat"],
                 extras={k[2:]: v for k, v in host.items() if k.startswith("x.")},
                 state={k[2:]: v for k, v in host.items() if k.startswith("s.")}, ready=ready)


_INDEX_CACHE: dict[tuple[tuple[int, ...], str], torch.Tensor] = {}


def _world_index(worlds: tuple[int, ...], device: torch.device) -> torch.Tensor | slice:
    """Rows ``worlds`` as an index that costs the device nothing per frame: a slice when they are
    consecutive, else an index tensor made on the device once per set of worlds. (Indexing a CUDA
    tensor with a Python list first copies the list from pageable memory, and CUDA synchronizes the
    stream before such a copy: a training thread would wait for the device up to 30 times a second.)"""
    if worlds == tuple(range(worlds[0], worlds[0] + len(worlds))):
        return slice(worlds[0], worlds[0] + len(worlds))
    key = (worlds, str(device))
    if key not in _INDEX_CACHE:
        if len(_INDEX_CACHE) > 64:  # the page changes the watched worlds rarely; keep a few
            _INDEX_CACHE.clear()
        _INDEX_CACHE[key] = torch.tensor(worlds, dtype=torch.long, device=device)
    return _INDEX_CACHE[key]


class FrameExchange:
    """The latest ``Frame``, written by the simulation thread, read by the streaming thread."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._wanted = threading.Event()
        self._published = threading.Condition(self._lock)
        self._frame: Frame | None = None
        self._sequence = 0

    def request(self) -> None:
        """The streaming thread wants a new frame after the next step."""
        self._wanted.set()

    def wanted(self) -> bool:
        """Whether the simulation thread should copy a frame now (one flag test per step)."""
        return self._wanted.is_set()

    def publish(self, frame: Frame) -> None:
        with self._lock:
            self._frame = frame
            self._sequence += 1
            self._wanted.clear()
            self._published.notify_all()

    def latest(self, after: int, timeout_s: float) -> tuple[int, Frame | None]:
        """The newest frame once its sequence number passes ``after`` (or at ``timeout_s``):
        (sequence, frame); the frame is None if nothing newer came."""
        with self._lock:
            self._published.wait_for(lambda: self._sequence > after, timeout=timeout_s)
            if self._sequence > after:
                return self._sequence, self._frame
            return after, None
