"""Cold-start time of a task on MuJoCo Warp: Warp's serial compile against ambulo's parallel precompile.

What a user waits for on a machine's first run: from ``envs.make`` to the end of the first env steps,
with an empty Warp kernel cache (``engine.warp_precompile``). Each measurement is its own process
with its own fresh cache folder (``WARP_CACHE_PATH``) and the CUDA driver's JIT cache off, run one
after another; the floor is the same process start against a warm cache (the parallel run's), where
nothing compiles: the fastest a first step can be.

    python benchmarks/warp_compile.py --device cuda                       # humanoid-rough, 0 vs 16 threads
    python benchmarks/warp_compile.py --device cpu --num-envs 4 --workers 0,2   # Warp's CPU device
    python benchmarks/warp_compile.py --device cuda --profile      # + where each run's compile time went
    python benchmarks/warp_compile.py --device cuda --processes 8  # + a cold run compiling in 8 forked processes

``--profile`` times Warp's compile steps in each run: the Python codegen (held under Warp's one codegen
lock, so serial whatever the threads), the native compile (Clang or NVRTC, run outside it), and how many
native compiles overlapped on average (``native_overlap``: their summed time over the wall time some ran;
near the thread count if nothing else serializes them), with the largest modules, and ``serial_native_s``:
the native compiles that ran one at a time on the critical path, outside the precompile's parallel loads (in
its dry run, or after it at a module's first launch: what the precompile missed), with their seconds.

``--processes N`` adds a third cold run: the parallel run's threads, with N forked processes compiling
the modules into the cache first (``PhysicsCfg.compile_processes``; one process's NVRTC compiles largely
one at a time). Its profile covers the parent process only.

``--cuda-output ptx|cubin`` makes Warp emit that format (``wp.config.cuda_output``) in every run; each run
reports the format Warp used (``cuda_output``). PTX is compiled again by the CUDA driver when a module
loads (its JIT cache, ``~/.nv/ComputeCache``, keeps the result unless ``CUDA_CACHE_DISABLE`` is set); a
cubin is final. ``--driver-cache`` adds two more cold runs with the parallel threads and an empty Warp
cache each, the driver's JIT cache on, in a folder of its own: empty for the first, and as the first left
it for the second (``parallel_driver_cold``, ``parallel_driver_warm``). On one H200 in session 22, runs of
``ambulo train`` with an empty Warp cache started ~45 s sooner after other runs on the machine than the
first one did; this tells whether the driver's cache is why.

Ends with ``RESULT {json}``: seconds per setting, ``speedup`` = serial / parallel,
``parallel_over_floor`` = parallel / warm and, with ``--processes``, ``processes_speedup`` = parallel /
processes and ``processes_over_floor`` = processes / warm.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time


def _profile_compiles() -> list:
    """Patch Warp's codegen and native compile to append ``(step, module, start, end)`` to the returned list,
    and GpuEngine's precompiles and their dry runs to append ``("precompile" | "dry_run", "", start, end)``."""
    import contextlib
    import threading

    from warp._src import build, context

    import ambulo.engine.gpu as gpu
    from ambulo.engine import warp_precompile

    spans, current = [], threading.local()

    def timed(owner, name: str, step: str, sets_module: bool = False):
        original = getattr(owner, name)

        def call(*args, **kwargs):
            if sets_module:
                current.module = args[0].name
            begin = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                spans.append((step, getattr(current, "module", "?"), begin, time.perf_counter()))

        setattr(owner, name, call)

    timed(context.Module, "load", "load", sets_module=True)
    timed(context.Module, "_run_codegen", "codegen")
    timed(build, "build_cpu", "native")
    timed(build, "build_cuda", "native")
    timed(gpu, "precompile", "precompile")  # GpuEngine calls it by this name
    recording = warp_precompile.recording_launches  # precompile calls it by this name

    @contextlib.contextmanager
    def timed_recording(*args, **kwargs):
        begin = time.perf_counter()
        try:
            with recording(*args, **kwargs):
                yield
        finally:
            spans.append(("dry_run", "", begin, time.perf_counter()))

    warp_precompile.recording_launches = timed_recording
    return spans


def _serial_native(spans: list) -> dict:
    """``{module: seconds}`` of the native compiles outside a precompile's parallel loads: in a dry run, or
    outside any precompile (a module's first launch compiling it). Both run one at a time on the caller's
    thread, so they add up on the cold start's critical path."""
    windows = {step: [(begin, end) for s, _, begin, end in spans if s == step] for step in ("precompile", "dry_run")}

    def within(step: str, begin: float, end: float) -> bool:
        return any(w_begin <= begin and end <= w_end for w_begin, w_end in windows[step])

    serial = {}
    for step, module, begin, end in spans:
        if step == "native" and (within("dry_run", begin, end) or not within("precompile", begin, end)):
            serial[module] = round(serial.get(module, 0.0) + end - begin, 2)
    return dict(sorted(serial.items(), key=lambda item: -item[1]))


def _profile_summary(spans: list) -> dict:
    total = {step: sum(end - begin for s, _, begin, end in spans if s == step) for step in ("codegen", "native")}
    native = sorted((begin, end, module) for step, module, begin, end in spans if step == "native")
    busy, reach = 0.0, float("-inf")  # wall time in which at least one native compile ran
    for begin, end, _ in native:
        busy += max(0.0, end - max(begin, reach))
        reach = max(reach, end)
    largest = sorted(native, key=lambda span: span[0] - span[1])[:5]
    return {"modules_compiled": len(native), "codegen_s": round(total["codegen"], 2),
            "native_s": round(total["native"], 2), "native_overlap": round(total["native"] / busy, 2) if busy else 0.0,
            "largest_native_s": {module: round(end - begin, 2) for begin, end, module in largest},
            "serial_native_s": _serial_native(spans)}


def child(task: str, device: str, num_envs: int, workers: int, profile: bool = False, processes: int = 0,
          cuda_output: str | None = None) -> dict:
    """In this process: time ``envs.make`` through two env steps of zero actions."""
    start = time.perf_counter()  # before the profile's hooks, which import torch and Warp as the run does
    spans = _profile_compiles() if profile else None
    import torch
    import warp as wp

    wp.config.cuda_output = cuda_output  # None: Warp's choice (PTX when the driver is at least its toolkit)

    import ambulo.envs as envs

    env = envs.make(task, num_envs=num_envs, device=device, engine="warp", seed=0,
                    **{"physics.compile_workers": workers, "physics.compile_processes": processes})
    env.reset()
    actions = torch.zeros(env.num_envs, env.num_actions, device=env.device)
    for _ in range(2):
        env.step(actions)
    if env.device.type == "cuda":
        torch.cuda.synchronize(env.device)
    engine = env.engine
    reports = getattr(engine, "precompile_reports", {})
    result = {"seconds": round(time.perf_counter() - start, 2),
              "engine_compile_s": round(engine.compile_time_s or 0.0, 2),
              "precompiled_modules": sum(r.modules for r in reports.values()),
              "compile_processes": sum(r.processes for r in reports.values()),
              "compile_process_failures": sum(r.process_failures for r in reports.values()),
              "cuda_output": wp.get_device(str(env.device)).get_cuda_output_format() if env.device.type == "cuda" else None}
    return result if spans is None else result | {"profile": _profile_summary(spans)}


def measure(args, workers: int, cache_dir: str, processes: int = 0, driver_cache_dir: str | None = None) -> dict:
    """One run in a process of its own, with ``cache_dir`` as Warp's kernel cache and the CUDA driver's JIT
    cache off, or in ``driver_cache_dir`` when given."""
    env = dict(os.environ, WARP_CACHE_PATH=cache_dir, CUDA_CACHE_DISABLE="1")
    if driver_cache_dir is not None:
        env.pop("CUDA_CACHE_DISABLE")
        env["CUDA_CACHE_PATH"] = driver_cache_dir
    command = [sys.executable, __file__, "--child", "--task", args.task, "--device", args.device,
               "--num-envs", str(args.num_envs), "--workers", str(workers),
               "--processes", str(processes)] + ["--profile"] * args.profile
    if args.cuda_output:
        command += ["--cuda-output", args.cuda_output]
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=False)
    lines = [line for line in done.stdout.splitlines() if line.startswith("CHILD ")]
    if done.returncode != 0 or not lines:
        raise SystemExit(f"the {workers}-thread run failed (exit {done.returncode}):\n{done.stderr[-3000:]}")
    return json.loads(lines[-1][len("CHILD "):])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="humanoid-rough")
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--workers", default="0,16",
                        help="serial,parallel thread counts (the first is the baseline; 0 = Warp's own serial compile)")
    parser.add_argument("--profile", action="store_true",
                        help="time Warp's codegen and native compiles in each run (adds a 'profile' entry per run)")
    parser.add_argument("--processes", type=int, default=0,
                        help="also time a cold run whose modules N forked processes compile first (0: no such run)")
    parser.add_argument("--cuda-output", choices=("ptx", "cubin"), default=None,
                        help="the CUDA format Warp emits in every run (default: Warp's choice)")
    parser.add_argument("--driver-cache", action="store_true",
                        help="also time two cold runs with the CUDA driver's JIT cache on: empty, then as the first left it")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        result = child(args.task, args.device, args.num_envs, int(args.workers), args.profile, args.processes,
                       args.cuda_output)
        print("CHILD " + json.dumps(result), flush=True)
        return
    import ambulo.envs as envs

    try:
        envs.spec(args.task)
    except KeyError as error:
        raise SystemExit(f"--task: {error.args[0]}") from None
    try:
        serial, parallel = (int(w) for w in args.workers.split(","))
    except ValueError:
        raise SystemExit(f"--workers {args.workers!r}: give two whole numbers, serial first, e.g. 0,16") from None
    results = {}
    with tempfile.TemporaryDirectory(prefix="ambulo-warp-cache-") as root:
        for name, workers in (("serial", serial), ("parallel", parallel)):
            results[name] = measure(args, workers, os.path.join(root, name))
            print(name, workers, results[name], flush=True)
        if args.processes > 1:
            results["processes"] = measure(args, parallel, os.path.join(root, "processes"), args.processes)
            print("processes", args.processes, results["processes"], flush=True)
        if args.driver_cache:  # an empty Warp cache each time; the driver's cache empty, then filled by the first
            driver_dir = os.path.join(root, "driver")
            for name in ("parallel_driver_cold", "parallel_driver_warm"):
                results[name] = measure(args, parallel, os.path.join(root, name), driver_cache_dir=driver_dir)
                print(name, results[name], flush=True)
        results["warm"] = measure(args, parallel, os.path.join(root, "parallel"))  # nothing left to compile
        print("warm", results["warm"], flush=True)
    seconds = {k: v["seconds"] for k, v in results.items()}
    result = {"task": args.task, "device": args.device, "num_envs": args.num_envs,
              "workers": {"serial": serial, "parallel": parallel}, "seconds": seconds, "runs": results,
              "speedup": round(seconds["serial"] / seconds["parallel"], 3),
              "parallel_over_floor": round(seconds["parallel"] / seconds["warm"], 3),
              "cuda_output": results["parallel"]["cuda_output"]}
    if "processes" in seconds:
        result |= {"processes": args.processes,
                   "processes_speedup": round(seconds["parallel"] / seconds["processes"], 3),
                   "processes_over_floor": round(seconds["processes"] / seconds["warm"], 3)}
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
