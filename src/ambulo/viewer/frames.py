"""The hand-over of poses from the simulation thread to the viewer's streaming thread.

The simulation never waits for the browser: the streaming thread asks for a frame (``request``)
at its capped rate, and the simulation, after its next step, copies one world's body poses (a
few hundred floats) into a new ``Frame`` and swaps it in under a lock held only for the swap.
Between requests a step costs one ``Event.is_set`` test. On a GPU the copy is asynchronous
(pinned memory, a CUDA event the streaming thread waits on), so the simulation thread never
synchronizes the device for the viewer.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np
import torch


@dataclass
class Frame:
    """One world's state at one instant, as the streaming thread reads it.

    Attributes:
      world: the world index.
      time_s: its simulated time, s.
      xpos_w: (nbody, 3) body positions, world frame, m.
      xquat_w: (nbody, 4) body orientations (w, x, y, z), world frame.
      extras: named (k,) values of that world (the env's command, its episode return), or empty.
    """

    world: int
    time_s: torch.Tensor
    xpos_w: torch.Tensor
    xquat_w: torch.Tensor
    extras: dict[str, torch.Tensor]
    ready: torch.cuda.Event | None = None
    paused: bool = False
    """Copied while the simulation thread was held by the page's pause (the state is frozen)."""

    def numpy(self) -> tuple[float, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """(time_s, xpos_w, xquat_w, extras) as host values; waits for a GPU copy to land."""
        if self.ready is not None:
            self.ready.synchronize()
        return (float(self.time_s), self.xpos_w.numpy(), self.xquat_w.numpy(),
                {k: v.numpy() for k, v in self.extras.items()})


def copy_world(world: int, time_s: torch.Tensor, xpos_w: torch.Tensor, xquat_w: torch.Tensor,
               extras: dict[str, torch.Tensor]) -> Frame:
    """A ``Frame`` of row ``world`` of the (N, ...) engine tensors and of ``extras`` (that world's
    values already), copied off the device without a sync."""
    rows = {"time": time_s[world], "xpos": xpos_w[world], "xquat": xquat_w[world]}
    rows.update({f"x.{k}": v for k, v in extras.items()})
    device = xpos_w.device
    if device.type == "cuda":
        host = {k: torch.empty(v.shape, dtype=v.dtype, pin_memory=True) for k, v in rows.items()}
        for k, v in rows.items():
            host[k].copy_(v, non_blocking=True)
        ready = torch.cuda.Event()
        ready.record(torch.cuda.current_stream(device))
    else:
        host, ready = {k: v.detach().clone() for k, v in rows.items()}, None
    return Frame(world=world, time_s=host["time"], xpos_w=host["xpos"], xquat_w=host["xquat"],
                 extras={k[2:]: v for k, v in host.items() if k.startswith("x.")}, ready=ready)


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
