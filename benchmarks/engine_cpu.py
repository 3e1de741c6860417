"""CpuEngine steps/s vs raw ``mujoco.batch.Batch`` on the same model and N (the ceiling).

    python benchmarks/engine_cpu.py [--num-worlds 256] [--steps 200] [--threads 0]

Both step the 21-DoF humanoid scene (built by ``ambulo.core``) with the same random
controls; ours includes torch control writes and divergence checks. The ceiling is the
faster of the two raw batch modes (persistent or not).
Prints the ratio and ends with one ``RESULT {json}`` line.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import mujoco
import numpy as np
import torch
from mujoco.batch import Batch

from ambulo.core import GroundCfg, PhysicsCfg, RobotCfg, add_ground, add_robot, compile_scene, new_scene
from ambulo.engine import CpuEngine


def humanoid_scene() -> mujoco.MjModel:
    """The bundled humanoid on the default ground, built by the core scene builder."""
    spec = new_scene("engine_bench")
    add_ground(spec, GroundCfg())
    add_robot(spec, RobotCfg(file="humanoid", prim_path="/World/robot"))
    return compile_scene(spec, PhysicsCfg(timestep_s=0.005))


def time_raw(model, n, steps, threads, ctrl, persistent: bool) -> float:
    batch = Batch(model, n, threads, persistent=persistent)
    bound = batch.bind("ctrl")
    batch.step(nstep=5)
    start = time.perf_counter()
    for t in range(steps):
        bound[:] = ctrl[t % len(ctrl)]
        batch.step()
    return n * steps / (time.perf_counter() - start)


def time_engine(model, n, steps, threads, ctrl) -> float:
    engine = CpuEngine(model, n, num_threads=threads)
    ctrl_t = torch.from_numpy(ctrl)
    engine.step(5)
    start = time.perf_counter()
    for t in range(steps):
        engine.ctrl[:] = ctrl_t[t % len(ctrl)]
        engine.step()
    return n * steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--num-worlds", type=int, nargs="+", default=[64, 256])
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--threads", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    model = humanoid_scene()
    figures = {}
    for n in args.num_worlds:
        # PD-hold-like controls around the standing pose, plus noise
        rng = np.random.default_rng(0)
        ctrl = rng.normal(0.0, 20.0, size=(50, n, model.nu))
        # best of interleaved repeats, so both see the same machine load
        raws, ourss = [], []
        for _ in range(args.repeats):
            # the ceiling is the faster raw mode: one MjData per thread, or one per world
            raws.append(max(time_raw(model, n, args.steps, args.threads, ctrl, persistent)
                            for persistent in (False, True)))
            ourss.append(time_engine(model, n, args.steps, args.threads, ctrl))
        raw, ours = max(raws), max(ourss)
        figures[n] = {"engine_steps_per_s": round(ours), "raw_batch_steps_per_s": round(raw),
                      "ratio": round(ours / raw, 3)}
        print(f"N={n:5d}: CpuEngine {ours:10.0f} steps/s   raw mujoco.batch {raw:10.0f} steps/s   "
              f"ratio {ours / raw:.3f}")
    worst = min(f["ratio"] for f in figures.values())
    print("RESULT " + json.dumps({"benchmark": "engine_cpu", "model": "humanoid (21 DoF) on plane",
                                  "cpus": os.cpu_count(), "per_n": figures, "ratio": worst}))


if __name__ == "__main__":
    main()
