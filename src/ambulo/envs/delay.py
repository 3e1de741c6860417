"""A per-world delay line: each world reads what was pushed ``delay[i]`` pushes ago.

Action latency and observation delay (``envs.transfer``) both need "the value from k steps ago,
k drawn per world": a ring of the last ``max_delay + 1`` pushes, read with one gather. The head
is a Python int (the push count), so nothing on the step path waits for the device.
"""

from __future__ import annotations

import torch

from ambulo.core.rows import put_rows, take_rows


class DelayBuffer:
    """Ring buffer of (N, *shape) values for per-world delays in [0, max_delay] pushes.

    Attributes:
      delay: (N,) int64 pushes each world lags by; set it (whole or by rows) at any time.
    """

    def __init__(self, max_delay: int, num_worlds: int, shape: tuple[int, ...], *, device, dtype=torch.float32):
        if max_delay < 0:
            raise ValueError(f"max_delay is {max_delay}: a delay counts pushes, give 0 or more")
        self.max_delay, self.num_worlds = int(max_delay), int(num_worlds)
        self.buffer = torch.zeros(self.max_delay + 1, num_worlds, *shape, dtype=dtype, device=device)
        self.delay = torch.zeros(num_worlds, dtype=torch.long, device=device)
        self._head = 0
        self._worlds = torch.arange(num_worlds, device=device)

    def push(self, value: torch.Tensor) -> None:
        """Add this step's (N, *shape) values."""
        self._head = (self._head + 1) % (self.max_delay + 1)
        self.buffer[self._head] = value

    def overwrite_latest(self, value: torch.Tensor) -> None:
        """Replace the latest push with (N, *shape) ``value`` (a value recomputed within one step)."""
        self.buffer[self._head] = value

    def read(self) -> torch.Tensor:
        """Each world's value from ``delay`` pushes ago (the latest push for delay 0)."""
        if self.max_delay == 0:
            return self.buffer[self._head]
        slot = (self._head - self.delay) % (self.max_delay + 1)
        return self.buffer[slot, self._worlds]

    def fill(self, rows: torch.Tensor | None, value: torch.Tensor) -> None:
        """Make every slot of the worlds ``rows`` selects (``core.rows``) hold ``value`` ((N or n,
        *shape)): after a reset a world has no past, and reading its "k steps ago" must not give
        another episode's values."""
        flat = self.buffer.reshape(self.max_delay + 1, self.num_worlds, -1)
        rows_value = take_rows(value, rows) if value.shape[0] == self.num_worlds else value
        for slot in range(self.max_delay + 1):  # slots, not worlds: max_delay + 1 writes
            put_rows(flat[slot], slice(None), rows_value.reshape(rows_value.shape[0], -1), rows)


__all__ = ["DelayBuffer"]
