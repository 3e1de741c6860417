"""One torch thread for the per-frame CPU work of perception (the TSDF's and the odometry's).

Why: a frame's CPU torch ops are small (a few thousand to a few hundred thousand elements), so
torch's intra-op pool gains little on them, and on a busy machine its OpenMP threads wait for cores
the other processes hold, spinning for milliseconds at every parallel region. Measured on a busy
2-core machine: the odometry took 222 ms median a frame (960 ms p90) with torch's 2 threads, against
59 ms quiet; the TSDF's voxel update 2.8 ms instead of 2.0. Both pin their torch work to the calling
thread with ``one_torch_thread`` (and restore the caller's setting after).
"""

from __future__ import annotations

from contextlib import contextmanager

import torch


@contextmanager
def one_torch_thread(device: torch.device | str):
    """Run the enclosed CPU torch ops on the calling thread only (a no-op for other devices, whose
    work is not torch's CPU pool); the previous thread count is restored on exit."""
    if torch.device(device).type != "cpu":
        yield
        return
    threads = torch.get_num_threads()
    if threads == 1:
        yield
        return
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


__all__ = ["one_torch_thread"]
