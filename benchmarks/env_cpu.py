"""Env-steps/s of humanoid-walk on the CPU engine vs the fastest raw ``mujoco.batch`` stepping.

Both sides step the same compiled model (with the env's per-world friction and masses), the
same number of worlds and physics steps (``decimation`` per env step) on the same threads,
from the same states: each timed env run records its physics inputs (state and controls
before each physics call, under a zero action; the recording's copies are not timed) and the
raw side replays exactly those, so pushes, falls and resets cost the ceiling the same solver
work (a standing robot converges in fewer solver iterations than a pushed one). The time to
copy a recorded state in is measured apart and subtracted. The ratio isolates the env's own cost: action
processing, observations, rewards, terminations, commands, pushes, sensors, episode
bookkeeping and resets. The ceiling is the fastest of four raw stepping modes (persistent or
not, with or without a final velocity-stage pass). Runs alternate (raw, env, raw, env, ...)
and the best of each is kept, which damps noise from other load.

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
STAGES = {"none": mujoco.mjtStage.mjSTAGE_NONE.value, "vel": mujoco.mjtStage.mjSTAGE_VEL.value}


def raw_batch(env, persistent: bool) -> mj_batch.Batch:
    """A batch of the env's model and per-world model fields."""
    engine = env.engine
    batch = mj_batch.Batch(env.model, env.num_envs, engine.batch.nthread, persistent=persistent)
    for name, values in engine._model_tensors.items():
        batch.expand(name)[:] = values.numpy()
    batch.set_const()
    return batch


def time_env(env, steps: int) -> tuple[float, list[tuple[np.ndarray, np.ndarray]]]:
    """Seconds for ``steps`` zero-action env steps, and the physics inputs (state and controls
    before each physics call) they used; the recording's copy time is not counted."""
    engine = env.engine
    inputs, step, copy_s = [], engine.step, [0.0]

    def recording(num_substeps=1, refresh=False):
        start = time.perf_counter()
        inputs.append((engine.batch.state.copy(), engine.ctrl.numpy().copy()))
        copy_s[0] += time.perf_counter() - start
        return step(num_substeps, refresh)

    engine.step = recording
    actions = torch.zeros(env.num_envs, env.num_actions)
    env.step(actions)
    inputs.clear()
    copy_s[0] = 0.0
    start = time.perf_counter()
    for _ in range(steps):
        env.step(actions)
    seconds = time.perf_counter() - start - copy_s[0]
    del engine.step  # back to the class's method
    return seconds, inputs


def time_raw(batch: mj_batch.Batch, inputs, nstep: int, stage: int | None) -> float:
    """Seconds for replaying ``inputs``: copy a state and controls in, then ``nstep`` physics
    steps (``stage`` None: the copies alone, which is subtracted)."""
    ctrl = batch.bind("ctrl")
    start = time.perf_counter()
    for state, control in inputs:
        batch.state[:] = state
        ctrl[:] = control
        if stage is not None:
            batch.step(nstep=nstep, stage=stage)
    return time.perf_counter() - start


def measure(num_envs: int, steps: int, repeats: int, num_threads: int) -> dict:
    env = ambulo.envs.make(TASK, num_envs=num_envs, seed=0, num_threads=num_threads)
    decimation = env.cfg.decimation
    time_env(env, 20)  # past the start: pushes, falls and resets are under way
    modes = {(persistent, stage): raw_batch(env, persistent)
             for persistent in (False, True) for stage in STAGES}
    raw_s = {mode: [] for mode in modes}
    env_s = []
    for _ in range(repeats):
        seconds, inputs = time_env(env, steps)
        env_s.append(seconds)
        # the raw side replays exactly the physics inputs of that env run
        copy = time_raw(modes[(False, "none")], inputs, decimation, None)
        for (persistent, stage), batch in modes.items():
            raw_s[(persistent, stage)].append(time_raw(batch, inputs, decimation, STAGES[stage]) - copy)
    best_mode = min(raw_s, key=lambda m: min(raw_s[m]))
    raw_best = min(raw_s[best_mode])
    raw_rate = num_envs * steps / raw_best
    env_rate = num_envs * steps / min(env_s)
    return {
        "num_envs": num_envs,
        "env_steps_per_s": round(env_rate),
        "raw_env_steps_per_s": round(raw_rate),
        "raw_mode": f"persistent={best_mode[0]}, stage={best_mode[1]}",
        "raw_ms_by_mode": {f"persistent={p},stage={st}": round(1e3 * min(v) / steps, 3)
                           for (p, st), v in raw_s.items()},
        "physics_steps_per_s": round(raw_rate * decimation),
        "ratio": round(env_rate / raw_rate, 3),
        "env_ms_per_step": round(1e3 * min(env_s) / steps, 3),
        "raw_ms_per_step": round(1e3 * raw_best / steps, 3),
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
              f"{r['ratio']:>6.3f} {r['env_ms_per_step']:>8.2f} {r['raw_ms_per_step']:>8.2f}   "
              f"ceiling: {r['raw_mode']} of {r['raw_ms_by_mode']}")
    result = {"task": TASK, "cpus": os.cpu_count(), "sizes": rows,
              "ratio": min(r["ratio"] for r in rows)}
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
