"""The batched path's randomizer draws on several processes: the CPU path's numbers, on every core.

Drawing a frame's scene (``Scatter2D``'s collision-checked placement above all) is a few ms of
Python on one core, while the GPU renders a frame in well under a tenth of that: with draws on
the producer's thread alone, a batch waits on them. A ``DrawPool`` runs the same
``apply_randomizers`` on ``workers`` spawned processes
(``BatchedFrameProducer(config, draws=DrawPool(config, workers))``), each with its own one-world
producer on Warp's CPU device (the same randomizers, host field copies and float32 rounding as the
producer's ``HostWorlds``, so the same numbers), and hands back each frame's log and the field
rows it wrote; the producer copies the rows into its ``HostWorlds`` and uploads as usual.

A frame's draws depend only on (config, seed, index), so which process draws it changes nothing,
as long as every randomizer writes the same fields each frame (the bundled ones do): a value
left over from an earlier frame would depend on which process drew that frame.
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import multiprocessing as mp
import os
import pickle
import signal
import threading
import time

_worker: dict = {}


class DrawPool:
    """``workers`` processes that draw frames' randomizations (see the module docstring)."""

    def __init__(self, config, workers: int):
        from .processes import _dump_config  # cloudpickle where the config holds local functions

        if workers < 1:
            raise ValueError(f"draw workers must be >= 1, got {workers}")
        self.workers = workers
        ctx = mp.get_context("spawn")
        self._barrier = ctx.Barrier(workers)
        self._pool = cf.ProcessPoolExecutor(workers, mp_context=ctx, initializer=_start_worker,
                                            initargs=(_dump_config(config), os.getpid(), self._barrier))

    def submit(self, seed: int, indices: list[int]) -> list[tuple[int, cf.Future]]:
        """Start drawing ``indices`` (in contiguous parts, one per process: frames of one
        ``every_n_frames`` block mostly stay together); returns (first position, future) pairs."""
        size = -(-len(indices) // self.workers)
        return [(start, self._pool.submit(_draw, seed, indices[start:start + size]))
                for start in range(0, len(indices), size)]

    def submit_call(self, fn, *args):
        """Run ``fn(*args)`` (a module-level function) on one of the processes; returns its future.
        What ``batched_disk`` writes a batch's files with: the processes hold the scene already."""
        return self._pool.submit(fn, *args)

    def warm(self) -> None:
        """Build every process's producer now (spawn, imports, scene: seconds), not on the first batch.
        One process first: with a cold Warp cache it compiles the render context's CPU kernels
        (a minute) once, and the others then load them."""
        self._pool.submit(_warm).result()
        for future in [self._pool.submit(_warm_together) for _ in range(self.workers)]:
            future.result()  # each waits for the others (a barrier): every process takes one

    @staticmethod
    def collect(parts: list[tuple[int, cf.Future]], host) -> list[dict]:
        """Wait for a ``submit``'s parts, write their rows into ``host`` (a ``HostWorlds``) at
        their positions, and return the frame logs in order."""
        logs: list[dict] = []
        for start, future in parts:
            part_logs, rows = future.result()
            host.set_rows(start, rows)
            logs.extend(part_logs)
        return logs

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


# -- in the worker processes ------------------------------------------------------------------

def _start_worker(payload: bytes, parent_pid: int, barrier) -> None:
    # exit when the parent process dies. Not PR_SET_PDEATHSIG (as ros2.publisher uses): that fires when the
    # parent *thread* that spawned this process ends, and a pool may be started from any thread
    threading.Thread(target=_exit_with, args=(parent_pid,), daemon=True).start()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's
    _worker.update(payload=payload, barrier=barrier)


def _exit_with(parent_pid: int) -> None:
    while os.getppid() == parent_pid:
        time.sleep(0.5)
    os._exit(1)


def _producer():
    if "producer" not in _worker:
        from .batched import BatchedFrameProducer

        config = pickle.loads(_worker["payload"])
        # draws do not depend on the image size: a tiny render context keeps the process small
        config = dataclasses.replace(config, camera=dataclasses.replace(config.camera, width=8, height=8))
        _worker["producer"] = BatchedFrameProducer(config, num_worlds=1, device="cpu")
    return _worker["producer"]


def _warm() -> None:
    _producer()


def _warm_together() -> None:
    try:
        _producer()
    except BaseException:
        _worker["barrier"].abort()  # the others would wait for this one forever
        raise
    _worker["barrier"].wait()


def _draw(seed: int, indices: list[int]) -> tuple[list[dict], dict]:
    """Each frame of ``indices`` drawn and applied on world 0 of this process's host copies;
    returns the logs and the rows of every field written, stacked (len(indices), ...)."""
    producer = _producer()
    logs, rows = [], []
    for index in indices:
        producer.host.begin()
        logs.append(producer.randomize_world(0, seed, index))
        rows.append(producer.host.rows(0, 1))
    import numpy as np

    stacked = {key: np.concatenate([r[key] for r in rows]) for key in rows[0]} if rows else {}
    return logs, stacked


__all__ = ["DrawPool"]
