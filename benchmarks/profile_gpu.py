"""Profile of humanoid-walk rollout steps on the GPU engine: what one env step spends, and where
it waits for the device.

After a warm-up (graphs captured, kernels loaded), ``--steps`` rollout steps (training's rollout
step on the runner ``ambulo train`` builds: the algorithm's ``act``, then ``env.step`` and the
step bookkeeping, as ``benchmarks/env_gpu.py`` times them) run under
``torch.profiler`` with CPU and CUDA activities. Ranges name the parts: ``rollout_step``,
``policy``, ``env.step``, ``engine.step`` and ``physics`` (the CUDA-graph launch of MuJoCo
Warp, or its eager launches on Warp's CPU device: ``wp.capture_launch`` and
``mujoco_warp.step/forward`` are wrapped for the run, so the trace names them).

Printed: the top ops by CUDA time and by CPU time; per step, the wall time (timed without the
profiler), the host time split into physics launch, torch ops and the rest (Python), the device
time split into Warp kernels (``*_cuda_kernel_*``), torch kernels and copies; and the host
round trips of the step path, found two ways: CUDA sync calls and device-to-host copies in the
trace, and torch's sync debug mode (``torch.cuda.set_sync_debug_mode("warn")``, ``env_gpu.count_syncs``)
over a separate run, whose warnings name the Python line that waited.

    python benchmarks/profile_gpu.py [--num-envs 4096] [--steps 20] [--trace trace.json]
    python benchmarks/profile_gpu.py --device cpu --num-envs 4 --steps 3 --warmup 2

Ends with one ``RESULT {json}`` line.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import datetime
import json
import time

import mujoco_warp as mjw
import torch
import warp as wp
from env_gpu import TASK, count_syncs, device_name, rollout_fns, sync
from torch.autograd import DeviceType
from torch.profiler import ProfilerActivity, profile, record_function

import ambulo.envs
from ambulo.engine.gpu import stack_versions

# CUDA runtime and driver calls that block the host until the device is done
SYNC_CALLS = ("cudaStreamSynchronize", "cudaDeviceSynchronize", "cudaEventSynchronize", "cudaMemcpy",
              "cuStreamSynchronize", "cuCtxSynchronize", "cuEventSynchronize", "cuMemcpyDtoH", "cuMemcpyDtoH_v2")
RANGES = ("rollout_step", "policy", "env.step", "engine.step", "physics")


@contextlib.contextmanager
def named_physics(engine):
    """Record-function ranges around the engine's physics launches and its ``step``."""
    originals = {"capture_launch": (wp, wp.capture_launch), "step": (mjw, mjw.step),
                 "forward": (mjw, mjw.forward)}

    def ranged(fn, name):
        def call(*args, **kwargs):
            with record_function(name):
                return fn(*args, **kwargs)
        return call

    for attr, (module, fn) in originals.items():
        setattr(module, attr, ranged(fn, "physics"))
    engine.step = ranged(type(engine).step.__get__(engine), "engine.step")
    try:
        yield
    finally:
        for attr, (module, fn) in originals.items():
            setattr(module, attr, fn)
        del engine.step


def rollout(act, step, obs, steps: int):
    for _ in range(steps):
        with record_function("rollout_step"):
            with record_function("policy"):
                actions = act(obs)
            with record_function("env.step"):
                obs, _ = step(actions)
    return obs


def _ancestors(evt):
    parent = evt.cpu_parent
    while parent is not None:
        yield parent
        parent = parent.cpu_parent


def _outermost(cpu, name: str) -> list[tuple[float, float]]:
    """(start, end) us of the ``name`` ranges not nested in another ``name`` range."""
    return [(e.time_range.start, e.time_range.end) for e in cpu
            if e.name == name and not any(a.name == name for a in _ancestors(e))]


def _inside(evt, spans) -> bool:
    start = evt.time_range.start
    return any(s <= start < e for s, e in spans)


def split(events, steps: int) -> dict:
    """Per-step host and device milliseconds from the profiler's events."""
    cpu = [e for e in events if e.device_type == DeviceType.CPU and not e.is_async]
    spans = {name: _outermost(cpu, name) for name in RANGES}
    host = {name: sum(e - s for s, e in spans[name]) / 1e3 / steps for name in RANGES}
    # torch ops: the outermost aten ops of the steps (their time includes the kernel launches)
    top_aten = [e for e in cpu if e.name.startswith("aten::") and _inside(e, spans["rollout_step"])
                and not any(a.name.startswith("aten::") for a in _ancestors(e))]
    torch_ms = sum(e.cpu_time_total for e in top_aten) / 1e3 / steps
    device = collections.Counter()
    for e in events:
        # our record_function ranges also appear as CUDA events spanning their kernels: skip
        # them, or every kernel would count twice (and the device look busier than the wall)
        if e.device_type != DeviceType.CUDA or e.name in RANGES:
            continue
        kind = ("memcpy_memset" if e.name.startswith(("Memcpy", "Memset"))
                else "warp_kernels" if "_cuda_kernel_" in e.name else "torch_kernels")
        device[kind] += (e.time_range.end - e.time_range.start) / 1e3 / steps
    total = host["rollout_step"]
    return {
        "host_ms_per_step": {"total": round(total, 3), "physics_launch": round(host["physics"], 3),
                             "torch_ops": round(torch_ms, 3),
                             "python_other": round(total - host["physics"] - torch_ms, 3)},
        "host_ms_by_range": {k: round(host[k], 3) for k in ("policy", "env.step", "engine.step")},
        "device_ms_per_step": {**{k: round(v, 3) for k, v in sorted(device.items())},
                               "total": round(sum(device.values()), 3)} if device else None,
    }


def host_round_trips(events, steps: int) -> dict:
    """Sync calls and device-to-host copies inside the profiled steps, per step."""
    cpu = [e for e in events if e.device_type == DeviceType.CPU]
    spans = _outermost(cpu, "rollout_step")
    calls = collections.Counter(e.name for e in cpu if e.name in SYNC_CALLS and _inside(e, spans))
    copies = sum(1 for e in events if e.device_type == DeviceType.CUDA and e.name.startswith("Memcpy DtoH"))
    scalar_reads = sum(1 for e in cpu if e.name == "aten::_local_scalar_dense" and _inside(e, spans))
    return {"sync_calls_per_step": round(sum(calls.values()) / steps, 2), "sync_calls": dict(calls),
            "dtoh_copies_per_step": round(copies / steps, 2),
            "scalar_reads_per_step": round(scalar_reads / steps, 2)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num-envs", type=int, default=4096)
    parser.add_argument("--device", default="cuda", help="cuda[:k], or cpu (Warp's CPU device)")
    parser.add_argument("--steps", type=int, default=20, help="profiled env steps")
    parser.add_argument("--warmup", type=int, default=30, help="env steps before profiling")
    parser.add_argument("--rows", type=int, default=15, help="rows of each table")
    parser.add_argument("--trace", help="write the Chrome trace (chrome://tracing, Perfetto) here")
    args = parser.parse_args()
    device = torch.device(args.device)
    env = ambulo.envs.make(TASK, num_envs=args.num_envs, device=args.device, engine="warp", seed=0)
    act, step, obs, policy = rollout_fns(env)
    with torch.inference_mode():
        obs = rollout(act, step, obs, args.warmup)
        sync(device)
        start = time.perf_counter()
        obs = rollout(act, step, obs, args.steps)
        sync(device)
        wall_ms = 1e3 * (time.perf_counter() - start) / args.steps

    activities = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if device.type == "cuda" else [])
    with named_physics(env.engine), torch.inference_mode(), profile(activities=activities) as prof:
        obs = rollout(act, step, obs, args.steps)
        sync(device)
    obs, warned = count_syncs(act, step, obs, args.steps, device)

    table = prof.key_averages()
    if device.type == "cuda":
        print(f"top {args.rows} by CUDA time ({args.steps} steps, N={args.num_envs})")
        print(table.table(sort_by="self_device_time_total", row_limit=args.rows, max_name_column_width=60))
    print(f"top {args.rows} by CPU time ({args.steps} steps, N={args.num_envs})")
    print(table.table(sort_by="self_cpu_time_total", row_limit=args.rows, max_name_column_width=60))
    if args.trace:
        prof.export_chrome_trace(args.trace)

    events = prof.events()
    parts = split(events, args.steps)
    trips = host_round_trips(events, args.steps)
    device_ms = (parts["device_ms_per_step"] or {}).get("total")
    result = {
        "benchmark": "profile_gpu", "task": TASK, "num_envs": args.num_envs, "steps": args.steps,
        "device": device_name(device), "policy": policy, "versions": stack_versions(),
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "wall_ms_per_step": round(wall_ms, 3), **parts,
        "device_busy_fraction": None if device_ms is None else round(device_ms / wall_ms, 3),
        "host_round_trips": trips, "torch_sync_warnings": warned,
    }
    host = parts["host_ms_per_step"]
    print(f"per env step: wall {wall_ms:.3f} ms unprofiled; host {host['total']:.3f} ms under the profiler "
          f"(physics launch {host['physics_launch']:.3f}, torch ops {host['torch_ops']:.3f}, "
          f"Python {host['python_other']:.3f}); device {device_ms} ms; "
          f"{trips['sync_calls_per_step']} sync calls, {trips['dtoh_copies_per_step']} DtoH copies per step")
    print("RESULT " + json.dumps(result), flush=True)


if __name__ == "__main__":
    main()
