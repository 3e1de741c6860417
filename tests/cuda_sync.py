"""torch's CUDA sync debug mode for a block: the GPU tests' check that a step path never waits on the device."""

from __future__ import annotations

import contextlib

import torch


@contextlib.contextmanager
def sync_debug(mode: str):
    """Inside the block, a host sync warns (``"warn"``) or raises (``"error"``); restored after it."""
    previous = torch.cuda.get_sync_debug_mode()
    torch.cuda.set_sync_debug_mode(mode)
    try:
        yield
    finally:
        torch.cuda.set_sync_debug_mode(previous)
