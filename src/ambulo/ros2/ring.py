"""The shared-memory ring between a ``Ros2Bridge`` (physics thread, writer) and its publisher process (reader).

Both processes map the same anonymous ``memfd`` (nothing is left in /dev/shm, whatever happens).
Ring (``Ring``): a header of int64 counters (``WRITTEN``, ``READ``, ``WAITING``) then ``slots`` rows of
float64; a row starts with the stamp (int64 ns) and the bit set of due topics, then the blocks that
``Layout`` names.
"""

from __future__ import annotations

import mmap
import threading
from dataclasses import dataclass, field

import numpy as np

WRITTEN, READ, WAITING = 0, 8, 16
"""int64 indices of the ring's counters, each on its own 64-byte cache line: ``WRITTEN`` is written by
the physics thread, ``READ`` by the publisher process and ``WAITING`` rarely, so no core's stores
evict a line the other core polls (false sharing cost the step path ~1 us)."""
HEADER_BYTES = 192
CLOCK, JOINT_STATES, TF, ODOM, IMU0 = 1, 2, 4, 8, 16
"""Bits of a slot's due topics; IMU i is ``IMU0 << i``."""


@dataclass
class Layout:
    """Where each block sits in a slot row (column offset, length)."""

    slots: int
    width: int = 2
    blocks: dict[str, tuple[int, int]] = field(default_factory=dict)

    def add(self, name: str, count: int) -> None:
        self.blocks[name] = (self.width, count)
        self.width += count

    @property
    def nbytes(self) -> int:
        return HEADER_BYTES + 8 * self.slots * self.width


class Ring:
    """The shared-memory ring over ``fd`` (both processes map the same ``memfd``)."""

    def __init__(self, fd: int, layout: Layout):
        self.map = mmap.mmap(fd, layout.nbytes)
        self.header = np.ndarray((HEADER_BYTES // 8,), np.int64, self.map, 0)
        self.rows = np.ndarray((layout.slots, layout.width), np.float64, self.map, HEADER_BYTES)
        self.irows = self.rows.view(np.int64)
        self.layout = layout

    def block(self, slot: int, name: str) -> np.ndarray:
        start, count = self.layout.blocks[name]
        return self.rows[slot, start:start + count]

    def close(self) -> None:
        del self.header, self.rows, self.irows
        self.map.close()


_FENCE = threading.Lock()


def fence() -> None:
    """A full memory barrier (taking a lock is an atomic read-modify-write): x86 may otherwise let a
    load pass an earlier store, and the ring's wake-up protocol (the bridge: store ``WRITTEN``, load
    ``WAITING``; the publisher: store ``WAITING``, load ``WRITTEN``) needs both to see one of them."""
    _FENCE.acquire()
    _FENCE.release()
