"""The disk mode's JPEG encode on a thread of its own, a batch behind the render.

torchvision's nvjpeg binding encodes a batch's images one after the other, waiting for the device
twice an image (``encode_jpegs_cuda``: the bitstream's length, then its copy): on the H200 0.2-0.3
ms of a 640x480 frame's 0.59 ms on the render's thread, which also waited there for the render
(``benchmarks/results/h200-2026-11-29-s7-generate-gpu.json``: ``jpeg_s`` 0.49 ms). ``JpegStage``
takes each batch's RGB images (``take``: a copy, queued on the render's stream, so the next render
may overwrite the camera's buffer), and a thread encodes them, copies the files into the batch's
shared block and hands the batch on (``put``'s ``then``), in batch order, while the render's
thread goes on with the next batch. The files are the same bytes: the same images, encoder and
quality.

On CUDA the render's thread must run on a stream of its own (``render_stream``): torchvision copies
each file out on the legacy default stream, which would otherwise wait for the next batch's
render (and the render for it). The ordering is explicit both ways: the encode starts once the
copy is done (waited on the host: torchvision before 0.22 did not order its encoder's stream after
the caller's), and the files are read after torchvision's copies on the default stream.
"""

from __future__ import annotations

import contextlib
import functools
import queue
import threading
import time
from collections.abc import Callable

import torch


class JpegStage:
    """Encodes batches on a thread (see the module docstring). ``encode``: (B, H, W, 3) uint8 ->
    list of B 1-D uint8 tensors (``encode.encode_jpegs``). ``failed`` holds the thread's error; the
    batches after it are not encoded (their ``drop`` runs: the caller frees their blocks)."""

    def __init__(self, device: torch.device, encode: Callable[[torch.Tensor], list[torch.Tensor]]):
        self.device, self.encode = torch.device(device), encode
        self.cuda = self.device.type == "cuda"
        self.stream, self.render_stream = _streams(self.device) if self.cuda else (None, None)
        """This thread's stream, and the one the render's thread runs on while the stage is open
        (``rendering``)."""
        self.failed: list[BaseException] = []
        self.encode_s = 0.0
        """Seconds the thread spent encoding and copying the files (its own wall time)."""
        self._queue: queue.Queue = queue.Queue()
        self._thread = threading.Thread(target=self._run, name="ambulo-jpeg", daemon=True)
        self._thread.start()

    @contextlib.contextmanager
    def rendering(self):
        """The render's thread's device work on ``render_stream`` (CUDA), ordered after what the
        current stream queued before and before what it queues after."""
        if not self.cuda:
            yield
            return
        caller = torch.cuda.current_stream(self.device)
        self.render_stream.wait_stream(caller)
        try:
            with torch.cuda.stream(self.render_stream):
                yield
        finally:
            caller.wait_stream(self.render_stream)

    def take(self, rgb: torch.Tensor) -> tuple[torch.Tensor, torch.cuda.Event | None]:
        """A copy of (B, H, W, 3) ``rgb`` for ``put``, queued on the current stream, and the event
        that marks it done (None off CUDA, where the copy is done on return). The copy is laid out
        as the encoder reads it (channels first): ``encode.encode_jpegs`` copies nothing more, so
        nvjpeg reads only memory this event covers."""
        copy = rgb.permute(0, 3, 1, 2).contiguous().permute(0, 2, 3, 1)
        if not self.cuda:
            return copy, None
        ready = torch.cuda.Event()
        ready.record(torch.cuda.current_stream(self.device))
        return copy, ready

    def put(self, taken: tuple, target: Callable[[int], object], then: Callable[[list[int]], None],
            drop: Callable[[], None]) -> None:
        """Encode ``take``'s images on the thread, write the files end to end into
        ``target(total bytes)`` (a NumPy uint8 array), then call ``then(file sizes)``; after an
        error, ``drop()`` instead. No images (a batch all of whose frames the
        CPU encodes): ``then([])``, in its turn."""
        self._queue.put((taken, target, then, drop))

    def close(self) -> None:
        """Encode what was put, then stop the thread (``failed`` says whether all went well)."""
        self._queue.put(None)
        self._thread.join()

    def _run(self) -> None:
        while (item := self._queue.get()) is not None:
            (images, ready), target, then, drop = item
            if self.failed:
                drop()
                continue
            try:
                start = time.perf_counter()
                sizes = self._encode(images, ready, target)
                self.encode_s += time.perf_counter() - start
            except BaseException as err:  # the render's thread raises it; this batch's block is freed
                self.failed.append(err)
                drop()
                continue
            try:
                then(sizes)
            except BaseException as err:
                self.failed.append(err)

    def _encode(self, images: torch.Tensor, ready, target) -> list[int]:
        if ready is not None:
            ready.synchronize()  # the copy is done before nvjpeg's stream reads it (see the module docstring)
        if len(images) == 0:  # every frame of the batch is the CPU's (``cpu_jpeg``): nothing to encode
            return []
        with torch.cuda.stream(self.stream) if self.cuda else contextlib.nullcontext():
            files = self.encode(images)
            if self.cuda:  # torchvision copies each file out on the legacy default stream
                copied = torch.cuda.Event()
                copied.record(torch.cuda.default_stream(self.device))
                self.stream.wait_event(copied)
            sizes = [int(f.numel()) for f in files]
            joined = torch.cat(files)
            out = torch.from_numpy(target(joined.numel()))
            out.copy_(joined, non_blocking=self.cuda)
            if self.cuda:
                self.stream.synchronize()  # the files are in the block before the processes read it
        return sizes


@functools.cache
def _streams(device: torch.device) -> tuple[torch.cuda.Stream, torch.cuda.Stream]:
    """(this thread's stream, the render's), made once per process: torch hands out its pool's
    streams in turn, so new ones every run would in time be the encoder's own. The render's is of
    high priority (another pool than torchvision's encoder stream), so its kernels go first."""
    return torch.cuda.Stream(device), torch.cuda.Stream(device, priority=-1)


__all__ = ["JpegStage"]
