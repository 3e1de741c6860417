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


def graph_step(env, actions, step_index: int, warmup: int):
    """``env.step(actions)`` of a ``cuda_graph`` env as its ``step_index``-th step: the ``warmup`` eager
    steps and the capture (which synchronizes once, by design) as they are, every replay under sync
    debug mode "error" (a host sync in the graph mode's step raises)."""
    if step_index <= warmup:
        return env.step(actions)
    with sync_debug("error"):
        return env.step(actions)
