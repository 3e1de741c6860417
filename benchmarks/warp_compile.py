"""Cold-start time of a task on MuJoCo Warp: Warp's serial compile against ambulo's parallel precompile.

What a user waits for on a machine's first run: from ``envs.make`` to the end of the first env steps,
with an empty Warp kernel cache (``engine.warp_precompile``). Each measurement is its own process
with its own fresh cache folder (``WARP_CACHE_PATH``) and the CUDA driver's JIT cache off, run one
after another; the floor is the same process start against a warm cache (the parallel run's), where
nothing compiles: the fastest a first step can be.

    python benchmarks/warp_compile.py --device cuda                       # humanoid-rough, 0 vs 16 threads
    python benchmarks/warp_compile.py --device cpu --num-envs 4 --workers 0,2   # Warp's CPU device

Ends with ``RESULT {json}``: seconds per setting, ``speedup`` = serial / parallel and
``parallel_over_floor`` = parallel / warm.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time


def child(task: str, device: str, num_envs: int, workers: int) -> dict:
    """In this process: time ``envs.make`` through two env steps of zero actions."""
    start = time.perf_counter()
    import torch

    import ambulo.envs as envs

    env = envs.make(task, num_envs=num_envs, device=device, engine="warp", seed=0,
                    **{"physics.compile_workers": workers})
    env.reset()
    actions = torch.zeros(env.num_envs, env.num_actions, device=env.device)
    for _ in range(2):
        env.step(actions)
    if env.device.type == "cuda":
        torch.cuda.synchronize(env.device)
    engine = env.engine
    reports = getattr(engine, "precompile_reports", {})
    return {"seconds": round(time.perf_counter() - start, 2),
            "engine_compile_s": round(engine.compile_time_s or 0.0, 2),
            "precompiled_modules": sum(r.modules for r in reports.values())}


def measure(args, workers: int, cache_dir: str) -> dict:
    env = dict(os.environ, WARP_CACHE_PATH=cache_dir, CUDA_CACHE_DISABLE="1")
    command = [sys.executable, __file__, "--child", "--task", args.task, "--device", args.device,
               "--num-envs", str(args.num_envs), "--workers", str(workers)]
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
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print("CHILD " + json.dumps(child(args.task, args.device, args.num_envs, int(args.workers))), flush=True)
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
        results["warm"] = measure(args, parallel, os.path.join(root, "parallel"))  # nothing left to compile
        print("warm", results["warm"], flush=True)
    seconds = {k: v["seconds"] for k, v in results.items()}
    print("RESULT " + json.dumps({
        "task": args.task, "device": args.device, "num_envs": args.num_envs,
        "workers": {"serial": serial, "parallel": parallel}, "seconds": seconds, "runs": results,
        "speedup": round(seconds["serial"] / seconds["parallel"], 3),
        "parallel_over_floor": round(seconds["parallel"] / seconds["warm"], 3)}))


if __name__ == "__main__":
    main()
