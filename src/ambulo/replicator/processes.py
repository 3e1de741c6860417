"""Frames of one dataset made by N local processes: each builds the scene once and renders chunks of frames.

Processes are started with 'spawn' (a fresh interpreter), never forked from
a process that may hold a GL context. Each one renders with the software
rasterizer inline (``LP_NUM_THREADS=0``): the processes already occupy the
cores, and llvmpipe's own threads would only add hand-offs between them.
Frame ``i`` depends only on (config, seed, i), so which process renders it
does not change its files; a frame counts once its record is written, after its
files, so a worker or parent killed at any instant leaves frames the next run
makes again, never a record of a partial file (``writers``).
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import os
import pickle
import signal
import sys
import threading
import time
from pathlib import Path

from .producer import FrameProducer, run_frames

LP_THREADS_ENV = "LP_NUM_THREADS"
_MIN_CHUNK, _MAX_CHUNK = 4, 256
"""Frames per task (``_chunks``). Each task is one ``run_frames``: at its end the render/write pipeline
drains and the batch's records wait on the file system's flush, with the process's core idle. Tasks
of 32 frames left ~4 % of the cores idle with 2 processes at 320x240 (CPU ms per frame vs frames/s);
256 frames of one process is ~2 s at 320x240, often enough for the progress bar. The smallest tasks
are the run's last: a process that takes the last one leaves the other idle until it is done, so they
are 4 frames (~35 ms at 320x240), not 16: 600 frames on 2 processes ended [..., 22, 16, 5] with 16 and
end [..., 11, 5, 4, 1] with 4; the processes' time outside their tasks (the end's imbalance, the
drains, the hand-outs) was 33 ms a run on average with 4 (13-74, 8 runs) against 66 with 16 (14-111,
7 runs), of ~2.6 s of the two cores at 320x240 (alternated, on the loaded 2-core VM)."""
# A worker process costs ~2 s to start (imports, scene, GL context), ~200 frames of one process at
# 320x240: below ~400 frames, 2 processes finish later than 1 (measured end to end on 2 cores).
_FRAMES_PER_WORKER = 200


def usable_cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def default_workers(num_frames: int) -> int:
    """One process per usable CPU, but no more than one per ~200 frames to make."""
    return max(1, min(usable_cpus(), num_frames // _FRAMES_PER_WORKER))


def prepare_producer_process() -> None:
    """Render inline in this process unless the user chose llvmpipe's thread count.

    Call before the first GL context: llvmpipe reads LP_NUM_THREADS once, when
    its screen is created. Ignored by GPU drivers.
    """
    os.environ.setdefault(LP_THREADS_ENV, "0")


class ProducerPool:
    """``workers`` spawned processes that write frames of (config, seed) into ``out``.

    Each process builds its ``FrameProducer`` on its first task. Use as a
    context manager; ``run`` may be called many times (the benchmark warms up
    first).
    """

    def __init__(self, config, out: str | Path, seed: int, workers: int, devices: list[str] | None = None,
                 num_worlds: int = 64):
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        if devices is not None and len(devices) != workers:
            raise ValueError(f"one device per worker: {workers} workers, devices {devices}")
        self.workers = workers
        self._batch = num_worlds if devices is not None else 0
        ctx = mp.get_context("spawn")
        self._barrier = ctx.Barrier(workers)
        # each batched worker takes the next device of the list when it starts
        self._next_device = ctx.Value("i", 0)
        self._pool = cf.ProcessPoolExecutor(
            workers, mp_context=ctx, initializer=_start_worker,
            initargs=(_dump_config(config), str(out), seed, os.getpid(), self._barrier,
                      devices, num_worlds, self._next_device))

    def run(self, frames: list[int], progress=None) -> str:
        """Render and write ``frames`` across the processes; returns the GL renderer string."""
        chunks = _chunks(frames, self.workers) if not self._batch else _batched_chunks(frames, self.workers,
                                                                                        self._batch)
        futures = {self._pool.submit(_run_chunk, chunk): len(chunk) for chunk in chunks}
        renderer = ""
        try:
            for fut in cf.as_completed(futures):
                renderer = fut.result()
                if progress is not None:
                    progress(futures[fut])
        except cf.process.BrokenProcessPool as err:
            raise RuntimeError(
                "a frame-producer process died (see its error above). Workers are spawned and import the "
                "main module: a script calling generate(workers > 1) needs `if __name__ == '__main__':`"
            ) from err
        except BaseException:  # Ctrl-C or a failed chunk: stop now rather than finish the queued chunks
            for fut in futures:
                fut.cancel()
            self._kill_workers()
            raise
        return renderer

    def run_on_each(self, fn, *args) -> list:
        """``fn(producer, *args)`` once in every process, started together (a barrier); call on an idle,
        fresh pool. For measurements such as the benchmark's render floor; ``fn`` must be picklable."""
        futures = [self._pool.submit(_on_each, fn, args) for _ in range(self.workers)]
        return [fut.result() for fut in futures]

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)

    def _kill_workers(self) -> None:
        # Safe at any instant: a killed worker leaves only temporaries (the next run removes them) and
        # files of frames whose record was not yet written (the next run makes those frames again).
        # (The executor has no public way to do it before Python 3.14's kill_workers.)
        for process in list((getattr(self._pool, "_processes", None) or {}).values()):
            process.kill()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def run_on_processes(config, out: Path, seed: int, frames: list[int], workers: int, progress=None,
                     devices: list[str] | None = None, num_worlds: int = 64) -> str:
    """Render ``frames`` on ``workers`` processes: CPU producers, or with ``devices`` (one per worker,
    e.g. ``["cuda:0", "cuda:1"]``) batched MuJoCo Warp producers of ``num_worlds`` worlds each."""
    with ProducerPool(config, out, seed, workers, devices, num_worlds) as pool:
        return pool.run(frames, progress)


def _chunks(frames: list[int], workers: int) -> list[list[int]]:
    """Tasks of shrinking size (guided self-scheduling): each takes a 1/workers share of the frames
    still unassigned, within [_MIN_CHUNK, _MAX_CHUNK]. Few tasks (few pipeline drains) while much is
    left, short ones at the end, so the processes finish together: one that is slowed down takes fewer
    of the later tasks (the pool hands out tasks in this order, each to the first free process)."""
    chunks, start = [], 0
    while start < len(frames):
        left = len(frames) - start
        size = min(left, _MAX_CHUNK, max(_MIN_CHUNK, -(-left // workers)))
        chunks.append(frames[start:start + size])
        start += size
    return chunks


def _batched_chunks(frames: list[int], workers: int, batch: int) -> list[list[int]]:
    """Whole launches per task (a multiple of ``batch`` frames), about four tasks per worker."""
    launches = max(1, len(frames) // (4 * workers * batch))
    size = launches * batch
    return [frames[i:i + size] for i in range(0, len(frames), size)]


def _dump_config(config) -> bytes:
    """The config for the spawned processes. cloudpickle copies by value what a new interpreter
    can't import by name: functions of a config file run by ``ambulo generate``, of a notebook or
    script (``__main__``), lambdas; plain pickle is the fallback without it."""
    try:
        import cloudpickle
    except ImportError:
        return pickle.dumps(config)
    return cloudpickle.dumps(config)


# -- in the worker processes ------------------------------------------------------

_worker: dict = {}


def _start_worker(payload: bytes, out: str, seed: int, parent_pid: int, barrier, devices=None, num_worlds=64,
                  next_device=None) -> None:
    _die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's: it stops the pool
    prepare_producer_process()
    device = None
    if devices is not None:
        with next_device.get_lock():
            device = devices[next_device.value % len(devices)]
            next_device.value += 1
    _worker.update(payload=payload, out=Path(out), seed=seed, barrier=barrier, device=device,
                   num_worlds=num_worlds, writer_threads=max(1, usable_cpus() // max(1, len(devices or [1]))))


def _producer():
    if "producer" not in _worker:
        _worker["config"] = pickle.loads(_worker["payload"])
        if _worker["device"] is None:
            _worker["producer"] = FrameProducer(_worker["config"])
        else:
            from .batched import BatchedFrameProducer

            _worker["producer"] = BatchedFrameProducer(_worker["config"], _worker["num_worlds"], _worker["device"])
    return _worker["producer"]


def _run_chunk(frames: list[int]) -> str:
    producer = _producer()
    threads = _worker["writer_threads"] if _worker["device"] is not None else 1
    return run_frames(_worker["config"], _worker["out"], _worker["seed"], frames, producer=producer,
                      writer_threads=threads)


def _on_each(fn, args):
    try:
        producer = _producer()
    except BaseException:
        _worker["barrier"].abort()  # the other workers would wait for this one forever
        raise
    _worker["barrier"].wait()
    return fn(producer, *args)


def _die_with_parent(parent_pid: int) -> None:
    """Exit when the parent dies (e.g. SIGKILL), so no orphan keeps writing into a dataset being resumed."""
    if sys.platform.startswith("linux"):
        import ctypes

        pr_set_pdeathsig = 1
        ctypes.CDLL(None).prctl(pr_set_pdeathsig, signal.SIGKILL)
    else:
        threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True).start()
    if os.getppid() != parent_pid:  # it died before we asked
        os._exit(1)


def _watch_parent(parent_pid: int) -> None:
    while os.getppid() == parent_pid:
        time.sleep(0.5)
    os._exit(1)
