"""Env-steps/s of humanoid-walk on the CPU engine vs raw ``mujoco.batch.Batch`` stepping.

Both sides step the same compiled model, the same number of worlds and physics steps
(``decimation`` per env step) on the same threads, holding the same PD targets (zero
action = the default pose), so the ratio isolates the env's own cost: action processing,
observations, rewards, terminations, episode bookkeeping and resets. Runs alternate
(raw, env, raw, env, ...) and the best of each is kept, which damps noise from other load.

    python benchmarks/env_cpu.py [--num-envs 256 1024] [--steps 100] [--repeats 3]

Ends with one line ``RESULT {json}``; "ratio" is the smallest env/raw ratio over the sizes.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import mujoco
import numpy as np
import torch
from mujoco import batch as mj_batch

import ambulo.envs

TASK = "humanoid-walk"


def time_env(env, steps: int) -> float:
    """Seconds for ``steps`` env steps (physics + actions + obs + rewards + resets)."""
    actions = torch.zeros(env.num_envs, env.num_actions)
    env.step(actions)
    start = time.perf_counter()
    for _ in range(steps):
        env.step(actions)
    return time.perf_counter() - start


def time_raw(batch: mj_batch.Batch, steps: int, nstep: int) -> float:
    """Seconds for ``steps`` batched calls of ``nstep`` physics steps each, nothing else."""
    stage = mujoco.mjtStage.mjSTAGE_VEL.value
    batch.step(nstep=nstep, stage=stage)
    start = time.perf_counter()
    for _ in range(steps):
        batch.step(nstep=nstep, stage=stage)
    return time.perf_counter() - start


def measure(num_envs: int, steps: int, repeats: int, num_threads: int) -> dict:
    env = ambulo.envs.make(TASK, num_envs=num_envs, seed=0, num_threads=num_threads)
    decimation = env.cfg.decimation
    # the raw batch starts from the env's reset state and holds the env's zero-action targets
    batch = mj_batch.Batch(env.model, num_envs, env.engine.batch.nthread, persistent=True)
    batch.state[:] = env.engine.batch.state
    env.step(torch.zeros(env.num_envs, env.num_actions))
    batch.bind("ctrl")[:] = env.engine.ctrl.numpy()
    raw_s, env_s = [], []
    for _ in range(repeats):
        raw_s.append(time_raw(batch, steps, decimation))
        env_s.append(time_env(env, steps))
    raw_rate = num_envs * steps / min(raw_s)
    env_rate = num_envs * steps / min(env_s)
    return {
        "num_envs": num_envs,
        "env_steps_per_s": round(env_rate),
        "raw_env_steps_per_s": round(raw_rate),
        "physics_steps_per_s": round(raw_rate * decimation),
        "ratio": round(env_rate / raw_rate, 3),
        "env_ms_per_step": round(1e3 * min(env_s) / steps, 3),
        "raw_ms_per_step": round(1e3 * min(raw_s) / steps, 3),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num-envs", type=int, nargs="+", default=[256, 1024])
    parser.add_argument("--steps", type=int, default=100, help="env steps per timed run")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=0, help="engine threads (0: all CPUs)")
    args = parser.parse_args()
    torch.set_num_threads(max(1, os.cpu_count() or 1))
    rows = [measure(n, args.steps, args.repeats, args.threads) for n in args.num_envs]
    print(f"{TASK}: env vs raw mujoco.batch at decimation {ambulo.envs.make_cfg(TASK).decimation}"
          f" ({os.cpu_count()} CPUs)")
    print(f"{'N':>6} {'env steps/s':>12} {'raw steps/s':>12} {'ratio':>6} "
          f"{'env ms':>8} {'raw ms':>8}")
    for r in rows:
        print(f"{r['num_envs']:>6} {r['env_steps_per_s']:>12} {r['raw_env_steps_per_s']:>12} "
              f"{r['ratio']:>6.3f} {r['env_ms_per_step']:>8.2f} {r['raw_ms_per_step']:>8.2f}")
    result = {"task": TASK, "cpus": os.cpu_count(), "sizes": rows,
              "ratio": min(r["ratio"] for r in rows)}
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
