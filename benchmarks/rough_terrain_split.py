"""Where humanoid-rough's env step spends its time against humanoid-walk's: physics vs the rest.

``benchmarks/rough_terrain.py`` gives the ratio (issue 30's bar: rough >= 50 % of flat); this
splits each task's ``env.step`` into the engine's ``step`` calls (physics: MuJoCo Warp's kernels
or MuJoCo's batch) and everything else (observations, height scan, rewards, resets, the action
latency's delay line). Each ``engine.step`` call is bracketed by device synchronizations, so on
CUDA the rest is the env's torch work run without overlap (an upper bound of what it adds to an
unsynchronized step). Also: the engine's contact and constraint-row buffers (``nconmax``,
``njmax``) and what the last step used (mean contacts per world, mean and max rows per world).

    python benchmarks/rough_terrain_split.py --device cuda --num-envs 4096 --steps 50
    python benchmarks/rough_terrain_split.py --device cpu --engine warp --num-envs 64 --steps 10

``--kernels N`` (CUDA only) also times MuJoCo Warp's kernels one by one (Warp's CUDA activity
timing, ``wp.ScopedTimer(cuda_filter=TIMING_KERNEL)``) over ``decimation`` x ``--steps`` raw
``mujoco_warp.step`` calls from the env's last state (no graph, no resets: robots may fall
meanwhile) and lists the N costliest per variant, ms per env step.

Ends with one ``RESULT {json}`` line: per variant ms per env step (``env``, ``physics``, ``rest``).
"""

from __future__ import annotations

import argparse
import json
import time

import torch

import ambulo.envs as envs

VARIANTS = {
    "flat": ("humanoid-walk", {}),
    "rough": ("humanoid-rough", {}),
    "rough_no_latency": ("humanoid-rough", {"transfer.action_latency_range_s": None}),
}


def sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def split(env, steps: int, warmup: int, generator: torch.Generator) -> dict:
    """ms per env step of the whole step (unsynchronized), of its engine.step calls and of the
    rest (each engine.step synchronized), and the buffers' use."""
    def act():
        return torch.rand(env.num_envs, env.num_actions, generator=generator, device=env.device) * 2 - 1

    def ms_per_step() -> float:
        sync(env.device)
        start = time.perf_counter()
        for _ in range(steps):
            env.step(act())
        sync(env.device)
        return (time.perf_counter() - start) / steps * 1e3

    for _ in range(warmup):
        env.step(act())
    env_ms = ms_per_step()

    engine, physics_s, calls = env.engine, [0.0], [0]
    step = engine.step

    def timed_step(*args, **kwargs):
        sync(env.device)
        t = time.perf_counter()
        out = step(*args, **kwargs)
        sync(env.device)
        physics_s[0] += time.perf_counter() - t
        calls[0] += 1
        return out

    engine.step = timed_step
    try:
        synced_ms = ms_per_step()
    finally:
        engine.step = step
    physics_ms = physics_s[0] / steps * 1e3
    out = {"env_ms": round(env_ms, 3), "synced_env_ms": round(synced_ms, 3), "physics_ms": round(physics_ms, 3),
           "rest_ms": round(synced_ms - physics_ms, 3), "engine_step_calls": calls[0] // steps}
    data = getattr(engine, "wp_data", None)
    if data is not None:  # MuJoCo Warp: its preallocated buffers and what the last step used
        nefc = torch.as_tensor(data.nefc.numpy()).float()
        out.update(nconmax=engine.nconmax, njmax=engine.njmax,
                   contacts_per_world=round(int(data.nacon.numpy()[0]) / env.num_envs, 2),
                   rows_per_world_mean=round(float(nefc.mean()), 1), rows_per_world_max=int(nefc.max()))
    return out


def kernel_split(env, steps: int, top: int) -> dict[str, float]:
    """ms per env step of each of MuJoCo Warp's kernels (the ``top`` costliest), CUDA only."""
    import collections

    import mujoco_warp as mjw
    import warp as wp

    engine = env.engine
    m, d = engine.wp_model, engine.wp_data
    with wp.ScopedDevice(engine.wp_device):
        mjw.step(m, d)
        wp.synchronize()
        with wp.ScopedTimer("physics", print=False, synchronize=True, cuda_filter=wp.TIMING_KERNEL) as timer:
            for _ in range(steps * env.cfg.decimation):
                mjw.step(m, d)
    ms = collections.Counter()
    for result in timer.timing_results:
        ms[result.name.split("_cuda_kernel")[0]] += result.elapsed / steps
    return {"total": round(sum(ms.values()), 3), **{k: round(v, 3) for k, v in ms.most_common(top)}}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--engine", default="auto", help="auto | mujoco | warp (warp on cpu: Warp's CPU device)")
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--warmup", type=int, default=10)
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--kernels", type=int, default=0, metavar="N",
                        help="CUDA: also list the N costliest MuJoCo Warp kernels per variant (raw steps)")
    args = parser.parse_args()
    generator = torch.Generator(device=args.device).manual_seed(0)
    results = {}
    for name in args.variants.split(","):
        task, overrides = VARIANTS[name]
        env = envs.make(task, num_envs=args.num_envs, device=args.device, engine=args.engine, seed=0, **overrides)
        results[name] = split(env, args.steps, args.warmup, generator)
        r = results[name]
        print(f"{name:17s} env {r['env_ms']:8.2f} ms | synced: physics {r['physics_ms']:8.2f} ms "
              f"({r['engine_step_calls']} calls), rest {r['rest_ms']:8.2f} ms | "
              + " ".join(f"{k}={r[k]}" for k in ("nconmax", "njmax", "contacts_per_world", "rows_per_world_mean",
                                                  "rows_per_world_max") if k in r), flush=True)
        if args.kernels and env.device.type == "cuda":
            r["kernels_ms"] = kernel_split(env, args.steps, args.kernels)
            print(f"  kernels (ms per env step, raw steps): {r['kernels_ms']}", flush=True)
        del env
    print("RESULT " + json.dumps({"device": args.device, "engine": args.engine, "num_envs": args.num_envs,
                                  "steps": args.steps, "split": results}))


if __name__ == "__main__":
    main()
