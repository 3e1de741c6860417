"""Compile the Warp modules a body of launches needs in parallel, before the body's first run.

Why: Warp compiles a module when one of its kernels is first launched, so a model's first MuJoCo
Warp step compiles its modules one after another (the humanoid's took ~2.4 min on an H200 host,
its 16 cores idle but one). Warp can load a list of modules from a thread pool
(``wp.force_load(max_workers=)``: NVRTC and Warp's CPU compiler are native calls that release the
GIL), but MuJoCo Warp builds most of its kernels in factories on a step's first call, so that list
does not exist before the step has run. ``precompile`` runs the body once with every launch
recorded instead of executed (kernels are created, modules found, nothing runs on the device),
then loads the recorded modules in parallel; the body's real first run finds them loaded.

What the dry run does not record (a launch made outside ``wp.launch`` / ``wp.launch_tiled``, a
kernel a later call creates) is compiled at its first launch as before: missing something costs
time, never correctness. Warp internals used: ``Kernel.is_generic`` and its overload resolution
(a generic kernel's module gains the overload at launch) and the launch's block-size resolution and
thread count (a launch of none loads nothing); on a Warp without them ``precompile`` raises and
``GpuEngine`` logs it and compiles serially.
"""

from __future__ import annotations

import contextlib
import inspect
import os
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import warp as wp

_MAX_DEFAULT_WORKERS = 16
"""The default's cap: each NVRTC compile of a large module holds a few hundred MB."""


def default_workers() -> int:
    """Threads for ``precompile`` when none are given: the machine's cores, at most 16."""
    return max(1, min(os.cpu_count() or 1, _MAX_DEFAULT_WORKERS))


@dataclass
class PrecompileReport:
    modules: int
    """Distinct (module, device, block size) variants the dry run recorded and loaded."""
    launches: int
    """Launches the dry run recorded (the body's launch count, repeats included)."""
    seconds: float
    """Wall time of the dry run and the parallel loads."""


def _resolve_block_dim(device, block_dim):
    """The block size ``wp.launch`` would load ``block_dim`` as on ``device`` (None: Warp's default)."""
    from warp._src import context

    return context._resolve_launch_block_dim(device, block_dim)


def _launch_size(dim) -> int:
    """Threads a launch of ``dim`` runs, as ``wp.launch`` counts them (the number it skips the launch on)."""
    from warp._src import context

    return context._normalize_launch_dim(dim)[1]


@contextlib.contextmanager
def recording_launches(variants: dict, counter: list[int]) -> Iterator[None]:
    """Within the block ``wp.launch`` and ``wp.launch_tiled`` run nothing: each call adds its kernel's
    module to ``variants[(device alias, block_dim)]`` (an insertion-ordered dict used as a set) and counts
    itself in ``counter[0]``. A launch of no threads is counted, not recorded: ``wp.launch`` returns before
    loading its module, so the real run never compiles it (MuJoCo Warp launches the features a model lacks,
    equality constraints, tendons, flexes, over a zero dimension). Device-side control flow is walked once:
    ``wp.capture_while`` runs its body once (its condition would never change, the kernels that change it
    not running) and ``wp.capture_if`` both branches. Only this thread's calls: the names are patched on
    the ``warp`` module, and another thread launching in the window (a viewer's renderer) runs its launches
    as ever. Callers that bound these names before the block are not intercepted."""
    signature = inspect.signature(wp.launch)
    originals = {name: getattr(wp, name) for name in ("launch", "launch_tiled", "capture_while", "capture_if")}
    recording_thread = threading.get_ident()

    def other_thread(name: str):
        """The original ``name`` when the caller is not the recording thread, else None."""
        return None if threading.get_ident() == recording_thread else originals[name]

    def record(*args, **kwargs):
        if (original := other_thread("launch")) is not None:
            return original(*args, **kwargs)
        arguments = signature.bind(*args, **kwargs).arguments
        if _launch_size(arguments["dim"]) == 0:  # wp.launch returns before loading the module: nothing to compile
            counter[0] += 1
            return
        kernel = arguments["kernel"]
        stream = arguments.get("stream")
        device = stream.device if stream is not None else wp.get_device(arguments.get("device"))
        if kernel.is_generic:  # as wp.launch: the overload for these argument types joins the module
            types = kernel.infer_argument_types([*arguments.get("inputs", ()), *arguments.get("outputs", ())])
            kernel = kernel._add_normalized_overload(types)
        block_dim = _resolve_block_dim(device, arguments.get("block_dim"))
        variants.setdefault((device.alias, block_dim), {})[kernel.module] = None
        counter[0] += 1

    def record_tiled(*args, **kwargs):
        if (original := other_thread("launch_tiled")) is not None:
            return original(*args, **kwargs)
        return record(*args, **kwargs)

    def capture_while(condition, while_body, stream=None, **kwargs):
        if (original := other_thread("capture_while")) is not None:
            return original(condition, while_body, stream=stream, **kwargs)
        if callable(while_body):
            while_body(**kwargs)

    def capture_if(condition, on_true=None, on_false=None, stream=None, **kwargs):
        if (original := other_thread("capture_if")) is not None:
            return original(condition, on_true, on_false, stream=stream, **kwargs)
        for branch in (on_true, on_false):
            if callable(branch):
                branch(**kwargs)

    wp.launch, wp.launch_tiled, wp.capture_while, wp.capture_if = record, record_tiled, capture_while, capture_if
    try:
        yield
    finally:
        for name, original in originals.items():
            setattr(wp, name, original)


def precompile(body: Callable[[], None], max_workers: int | None = None) -> PrecompileReport:
    """Run ``body`` with its launches recorded, not executed, then load every module it launches from
    ``max_workers`` threads (None: ``default_workers()``). ``body``'s other effects (array copies,
    fills) do happen: run it on state the caller restores or is about to overwrite."""
    start = time.perf_counter()
    variants: dict = {}
    counter = [0]
    with recording_launches(variants, counter):
        body()
    workers = default_workers() if max_workers is None else max_workers
    for (device, block_dim), modules in variants.items():
        wp.force_load(device=device, modules=list(modules), block_dim=block_dim, max_workers=workers)
    return PrecompileReport(modules=sum(len(m) for m in variants.values()), launches=counter[0],
                            seconds=time.perf_counter() - start)
