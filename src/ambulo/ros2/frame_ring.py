"""Camera frames from the physics process to the publisher process through shared memory.

A 640x480 image is 0.9 MB (rgb8) or 1.2 MB (32FC1 depth). Pickled over the bridge's socket it was
copied four times and the physics thread blocked while the publisher process read it in socket-buffer
sized pieces (p99 latency 11 ms on 2 cores). Here the physics thread writes the serialized message
once, straight into a slot of an anonymous ``memfd`` that both processes map, and sends only the
slot's number over the socket; the publisher publishes the slot's bytes and frees it.

Layout: three int64 counters, each on its own 64-byte cache line (``WRITTEN`` is the bridge's,
``READ`` the publisher's: no false sharing between the two cores), then ``slots`` slots of
``slot_bytes``. Slots are used in order, so ``WRITTEN - READ`` is the number in flight.
"""

from __future__ import annotations

import mmap
import os

import numpy as np

WRITTEN, READ = 0, 8
"""int64 indices of the counters (64 bytes apart)."""
HEADER_BYTES = 128


class FrameRing:
    """``slots`` buffers of ``slot_bytes`` in the shared memory behind ``fd``."""

    def __init__(self, fd: int, slots: int, slot_bytes: int):
        self.slots, self.slot_bytes = slots, slot_bytes
        self.map = mmap.mmap(fd, HEADER_BYTES + slots * slot_bytes)
        self.header = np.ndarray((HEADER_BYTES // 8,), np.int64, self.map, 0)
        self.data = np.ndarray((slots, slot_bytes), np.uint8, self.map, HEADER_BYTES)

    @classmethod
    def create(cls, slots: int, slot_bytes: int) -> tuple[FrameRing, int]:
        """A new ring and its memfd (the caller passes the fd to the other process, then closes it)."""
        fd = os.memfd_create("ambulo-ros2-frames")  # anonymous: nothing is left in /dev/shm
        os.ftruncate(fd, HEADER_BYTES + slots * slot_bytes)
        return cls(fd, slots, slot_bytes), fd

    def in_flight(self) -> int:
        return int(self.header[WRITTEN] - self.header[READ])

    def put(self, prefix: bytes, pixels: np.ndarray) -> int | None:
        """Write ``prefix`` then ``pixels``' bytes into the next slot; returns the slot's size in bytes,
        or None when every slot is still waiting for the publisher."""
        if self.in_flight() >= self.slots:
            return None
        nbytes = len(prefix) + pixels.nbytes
        if nbytes > self.slot_bytes:
            raise ValueError(f"a {nbytes}-byte frame does not fit the {self.slot_bytes}-byte slots: a camera "
                             "changed resolution after the bridge started; restart the bridge")
        row = self.data[int(self.header[WRITTEN]) % self.slots]
        row[:len(prefix)] = np.frombuffer(prefix, np.uint8)
        row[len(prefix):nbytes] = pixels.reshape(-1).view(np.uint8)
        self.header[WRITTEN] += 1
        return nbytes

    def take(self, nbytes: int) -> bytes:
        """The oldest slot's message (a copy: rclpy publishes ``bytes``); frees the slot."""
        read = int(self.header[READ])
        data = self.data[read % self.slots, :nbytes].tobytes()
        self.header[READ] = read + 1
        return data

    def close(self) -> None:
        del self.header, self.data
        self.map.close()


def slot_bytes_for(width: int, height: int, frame_id: str) -> int:
    """Room for one serialized Image of the largest encoding the bridge sends (32FC1: 4 bytes a pixel)
    plus its header fields (stamp, frame id, sizes, encoding), rounded up to a 4 KiB page."""
    size = 4 * width * height + 64 + len(frame_id.encode())
    return -(-size // 4096) * 4096


__all__ = ["FrameRing", "slot_bytes_for"]
