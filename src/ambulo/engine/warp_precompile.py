"""Compile the Warp modules a body of launches needs in parallel, before the body's first run.

Why: Warp compiles a module when one of its kernels is first launched, so a model's first MuJoCo
Warp step compiles its modules one after another (the humanoid's took ~2.4 min on an H200 host,
its 16 cores idle but one). Warp can load a list of modules from a thread pool
(``wp.force_load(max_workers=)``: NVRTC and Warp's CPU compiler are native calls that release the
GIL), but MuJoCo Warp builds most of its kernels in factories on a step's first call, so that list
does not exist before the step has run. ``precompile`` runs the body once with every launch
recorded instead of executed (kernels are created, modules found, nothing runs on the device),
then loads the recorded modules in parallel; the body's real first run finds them loaded.

A body may also ask Warp for a kernel's CUDA occupancy (``wp.get_suggested_block_size``: MuJoCo
Warp sizes its CCD, broadphase and sparse-gradient grids so), which loads the kernel's module at
its default block size: in the dry run, one compile after another (on an H200 host the humanoid's
CCD module, 41 s to compile, was one of them). The dry run answers such a query with a stand-in
and records that variant too; a body that got stand-ins is dry-run again once the loads are done,
now with the real answers, as a grid size can choose a kernel (MuJoCo Warp's deterministic
sparse gradient), and what that pass adds is loaded in turn, until a pass needs no stand-in.

What the dry run still does not record (a launch made outside ``wp.launch`` / ``wp.launch_tiled``,
a kernel a later call creates) is compiled at its first launch as before: missing something costs
time, never correctness. Warp internals used: ``Kernel.is_generic`` and its overload resolution
(a generic kernel's module gains the overload at launch) and the launch's block-size resolution and
thread count (a launch of none loads nothing); on a Warp without them ``precompile`` raises and
``GpuEngine`` logs it and compiles serially.
"""

from __future__ import annotations

import contextlib
import inspect
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import warp as wp

_MAX_DEFAULT_WORKERS = 16
"""The default's cap: each NVRTC compile of a large module holds a few hundred MB."""

_MAX_PASSES = 3
"""Dry runs of one body at most: the first answers occupancy queries with stand-ins, the second with
the real answers; a third only if the second's answers chose kernels whose queries were new."""


def default_workers() -> int:
    """Threads for ``precompile`` when none are given: the machine's cores, at most 16."""
    return max(1, min(os.cpu_count() or 1, _MAX_DEFAULT_WORKERS))


@dataclass
class PrecompileReport:
    modules: int
    """Distinct (module, device, block size) variants the dry runs recorded and loaded."""
    launches: int
    """Launches the last dry run recorded (the body's launch count, repeats included)."""
    seconds: float
    """Wall time of the dry runs and the parallel loads."""
    processes: int = 0
    """Child processes that compiled into the kernel cache before the loads (0: threads only)."""
    process_failures: int = 0
    """Children that failed or timed out (what they missed compiles in the loads, from threads)."""
    passes: int = 1
    """Dry runs of the body: more than one when an occupancy query got a stand-in (module docstring)."""


def _resolve_block_dim(device, block_dim):
    """The block size ``wp.launch`` would load ``block_dim`` as on ``device`` (None: Warp's default)."""
    from warp._src import context

    return context._resolve_launch_block_dim(device, block_dim)


def _launch_size(dim) -> int:
    """Threads a launch of ``dim`` runs, as ``wp.launch`` counts them (the number it skips the launch on)."""
    from warp._src import context

    return context._normalize_launch_dim(dim)[1]


def _is_loaded(module, device, block_dim) -> bool:
    """Whether ``module.load(device, block_dim)`` would return at once: that variant is loaded and current
    (Warp internals: ``Module.execs`` keyed by device context and block size, checked against the hash)."""
    loaded = module.execs.get((device.context, block_dim))
    return loaded is not None and (module.options["strip_hash"] or loaded.module_hash == module.get_module_hash(block_dim))


def _occupancy_variant(kernel, device):
    """The (module, block size) a ``wp.get_suggested_block_size(kernel, device)`` call would load now, or None
    where it loads nothing new: not on CUDA (Warp answers (1, 1) there), a generic kernel (Warp raises), or
    the variant is loaded. Warp loads the module at its default block size (``Module.load(device)``), not the
    one the kernel is later launched with: a variant of its own."""
    if not device.is_cuda or kernel.is_generic:
        return None
    block_dim = kernel.module.options["block_dim"]
    return None if _is_loaded(kernel.module, device, block_dim) else (kernel.module, block_dim)


def _stand_in_answer(block_dim: int, device) -> tuple[int, int]:
    """The dry run's answer to an occupancy query it does not compile for: plausible and positive (one block
    of the default size per SM). It sizes grids the dry run never launches; what it may select (a kernel
    variant) the next pass, with the real answer, records."""
    return block_dim, max(1, device.sm_count)


@contextlib.contextmanager
def recording_launches(variants: dict, counter: list[int], stand_ins: list | None = None) -> Iterator[None]:
    """Within the block ``wp.launch`` and ``wp.launch_tiled`` run nothing: each call adds its kernel's
    module to ``variants[(device alias, block_dim)]`` (an insertion-ordered dict used as a set) and counts
    itself in ``counter[0]``. A launch of no threads is counted, not recorded: ``wp.launch`` returns before
    loading its module, so the real run never compiles it (MuJoCo Warp launches the features a model lacks,
    equality constraints, tendons, flexes, over a zero dimension). Device-side control flow is walked once:
    ``wp.capture_while`` runs its body once (its condition would never change, the kernels that change it
    not running) and ``wp.capture_if`` both branches. ``wp.get_suggested_block_size`` on a module variant not
    loaded yet records that variant, answers (default block size, SM count) in place of compiling it
    serially, and appends the kernel's key to ``stand_ins`` (``precompile`` then dry-runs the body again
    for the real answers); elsewhere it answers as ever. Only this thread's calls: the names are patched on
    the ``warp`` module, and another thread launching in the window (a viewer's renderer) runs its launches
    as ever. Callers that bound these names before the block are not intercepted."""
    signature = inspect.signature(wp.launch)
    names = ("launch", "launch_tiled", "capture_while", "capture_if", "get_suggested_block_size")
    originals = {name: getattr(wp, name) for name in names}
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

    def suggested_block_size(kernel, device=None):
        if (original := other_thread("get_suggested_block_size")) is not None:
            return original(kernel, device)
        target = wp.get_device(device)
        variant = _occupancy_variant(kernel, target) if isinstance(kernel, wp.Kernel) else None
        if variant is None:  # nothing to compile: the real answer is cheap
            return originals["get_suggested_block_size"](kernel, device)
        module, block_dim = variant
        variants.setdefault((target.alias, block_dim), {})[module] = None
        if stand_ins is not None:
            stand_ins.append(kernel.key)
        return _stand_in_answer(block_dim, target)

    patched = (record, record_tiled, capture_while, capture_if, suggested_block_size)
    for name, function in zip(names, patched):
        setattr(wp, name, function)
    try:
        yield
    finally:
        for name, original in originals.items():
            setattr(wp, name, original)


def _compile_into_cache(module, device, block_dim) -> None:
    """What ``Module.load`` does before it loads: the module's binary for ``block_dim`` compiled into
    Warp's kernel cache (nothing if it is there), without loading it into a device context. Warp
    internals: the options, output name and arch ``load`` resolves, then ``Module._compile``."""
    module.get_module_hash(block_dim)  # resolves (and keeps) this block size's options
    options = module.resolved_options[block_dim]
    output_name = module._get_compile_output_name(device, block_dim=block_dim)
    output_arch = module._get_compile_arch(device)
    module_dir = os.path.join(wp.config.kernel_cache_dir, module.get_module_identifier(block_dim))
    module._compile(device, module_dir, output_name, output_arch, options=options)


def compile_in_processes(variants: dict, processes: int, timeout_s: float = 900.0) -> tuple[int, int]:
    """Compile the recorded ``variants`` into Warp's kernel cache from ``processes`` forked children,
    the modules dealt round-robin; returns (children started, children that failed or timed out).

    Why processes: in one process NVRTC compiles largely one at a time (16 threads overlapped 2.2
    compiles on average on an H200 host, session 21), and Warp's codegen holds a lock; each child
    has its own. A fork inherits the recorded modules, so a child needs no model of its own; it only
    generates code and runs the compiler (no device context is touched), and Warp's cache writes
    (a per-process build folder renamed into place) are safe between processes. A child that fails
    costs time, not correctness: the parent's loads compile what is missing."""
    jobs = [(device, block_dim, module) for (device, block_dim), modules in variants.items() for module in modules]
    if processes <= 1 or len(jobs) < 2 or not hasattr(os, "fork"):
        return 0, 0
    children = []
    for k in range(min(processes, len(jobs))):
        pid = os.fork()
        if pid == 0:  # the child: compile its share and leave at once (no atexit, no torch teardown)
            code = 0
            try:
                for device, block_dim, module in jobs[k::processes]:
                    try:
                        _compile_into_cache(module, wp.get_device(device), block_dim)
                    except Exception:
                        code = 1
            finally:
                os._exit(code)
        children.append(pid)
    deadline, failed = time.monotonic() + timeout_s, 0
    for pid in children:
        while True:
            done, status = os.waitpid(pid, os.WNOHANG)
            if done:
                failed += int(not os.WIFEXITED(status) or os.WEXITSTATUS(status) != 0)
                break
            if time.monotonic() > deadline:
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
                failed += 1
                break
            time.sleep(0.05)
    return len(children), failed


def _unloaded(variants: dict) -> dict:
    """``variants`` less those loaded and current: what a later pass adds to the earlier passes' loads."""
    left = {}
    for (device, block_dim), modules in variants.items():
        target = wp.get_device(device)
        todo = [module for module in modules if not _is_loaded(module, target, block_dim)]
        if todo:
            left[(device, block_dim)] = dict.fromkeys(todo)
    return left


def _load(variants: dict, workers: int, processes: int) -> tuple[int, int]:
    """Compile and load ``variants``: forked ``processes`` into the kernel cache first (when more than 1),
    then ``workers`` threads; returns ``compile_in_processes``' (children started, children failed)."""
    started, failed = compile_in_processes(variants, processes)
    for (device, block_dim), modules in variants.items():
        wp.force_load(device=device, modules=list(modules), block_dim=block_dim, max_workers=workers)
    return started, failed


def precompile(body: Callable[[], None], max_workers: int | None = None, processes: int = 0) -> PrecompileReport:
    """Run ``body`` with its launches recorded, not executed, then load every module it launches from
    ``max_workers`` threads (None: ``default_workers()``); with ``processes`` > 1, forked children
    first compile the modules into the kernel cache (``compile_in_processes``) and the threads then
    load them from it. A body whose occupancy queries got stand-ins is dry-run again after the loads
    (module docstring), at most ``_MAX_PASSES`` times in all. ``body``'s other effects (array copies,
    fills) do happen, once a pass: run it on state the caller restores or is about to overwrite."""
    start = time.perf_counter()
    workers = default_workers() if max_workers is None else max_workers
    loaded: dict = {}  # every variant a pass loaded, for the report
    started = failed = passes = 0
    while passes < _MAX_PASSES:
        passes += 1
        variants, counter, stand_ins = {}, [0], []
        with recording_launches(variants, counter, stand_ins):
            body()
        # the first pass loads all it recorded, as ever (loaded ones return at once); a later pass what is new
        new = variants if passes == 1 else _unloaded(variants)
        more_started, more_failed = _load(new, workers, processes)
        started, failed = started + more_started, failed + more_failed
        for key, modules in variants.items():
            loaded.setdefault(key, {}).update(modules)
        if not stand_ins:  # every answer was real: this pass recorded what the real run launches
            break
    return PrecompileReport(modules=sum(len(m) for m in loaded.values()), launches=counter[0],
                            seconds=time.perf_counter() - start, processes=started, process_failures=failed,
                            passes=passes)
