"""How the GPU engine's contact and constraint buffers cost speed, and how full they get.

MuJoCo Warp preallocates ``nconmax`` contacts and ``njmax`` constraint rows per world; several
kernels work over the whole allocation, so larger buffers step slower, and a buffer that is too
small drops contacts (``GpuEngine`` then raises ``EngineOverflowError``). This measures, for
``humanoid-walk`` at N worlds:

  * the largest contact count and constraint-row count any world reached over a rollout of
    random actions (falls, pushes and resets included), tracked on the device;
  * raw ``mujoco_warp.step`` rates (decimation steps in one CUDA graph, from the rollout's final
    state) at three buffer sizes: the engine's (``contact_capacity``), MuJoCo Warp's own
    defaults, and 1.5x the measured peak.

RESULT ratio: the engine's sizes against the fastest of the three.

    python benchmarks/buffers_gpu.py [--num-envs 4096] [--steps 150] [--device cuda]
"""

from __future__ import annotations

import argparse
import json
import time

import mujoco
import mujoco_warp as mjw
import torch
import warp as wp
from env_gpu import RawWarp, sync

import ambulo.envs


def peak_usage(env, steps: int, generator: torch.Generator) -> tuple[int, int]:
    """(max contacts in one world, max constraint rows in one world) over ``steps`` env steps."""
    d, n = env.engine.wp_data, env.num_envs
    max_con = torch.zeros((), dtype=torch.long, device=env.device)
    max_efc = torch.zeros((), dtype=torch.long, device=env.device)
    worldid = wp.to_torch(d.contact.worldid)
    nacon = wp.to_torch(d.nacon)
    nefc = env.engine.field("nefc")
    slots = torch.arange(worldid.shape[0], device=env.device)
    for _ in range(steps):
        actions = torch.randn(n, env.num_actions, generator=generator, device=env.device)
        env.step(actions)
        live = slots < nacon[0]
        counts = torch.bincount(worldid.long().clamp(0, n - 1)[live], minlength=n)
        max_con = torch.maximum(max_con, counts.max())
        max_efc = torch.maximum(max_efc, nefc.max().long())
    return int(max_con), int(max_efc)


def raw_rate(engine, nconmax: int, njmax: int, nstep: int, launches: int) -> float:
    """Physics steps/s of raw ``mujoco_warp.step`` at these buffer sizes (env_gpu's ceiling: a
    CUDA graph of ``nstep`` steps), from the engine's current state; best of 3."""
    raw = RawWarp(engine, nstep, nconmax=nconmax, njmax=njmax)
    best = float("inf")
    for _ in range(3):
        torch._foreach_copy_(raw.state, [engine.field(n) for n in raw.names])
        sync(engine.device)
        start = time.perf_counter()
        for _ in range(launches):
            raw.launch()
        sync(engine.device)
        best = min(best, time.perf_counter() - start)
    return engine.num_worlds * nstep * launches / best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num-envs", type=int, default=4096)
    parser.add_argument("--steps", type=int, default=150)
    parser.add_argument("--launches", type=int, default=50)
    parser.add_argument("--device", default="cuda")
    args = parser.parse_args()
    env = ambulo.envs.make("humanoid-walk", num_envs=args.num_envs, device=args.device, engine="warp", seed=0)
    engine = env.engine
    gen = torch.Generator(device=env.device).manual_seed(0)
    peak_con, peak_efc = peak_usage(env, args.steps, gen)
    data0 = mujoco.MjData(engine.model)
    mujoco.mj_forward(engine.model, data0)
    sizes = {
        "engine": (engine.nconmax, engine.njmax),
        "mujoco_warp_default": (mjw._src.io._default_nconmax(engine.model, data0),
                                mjw._src.io._default_njmax(engine.model, data0)),
        "measured_peak_x1.5": (max(8, int(1.5 * peak_con)), max(8, int(1.5 * peak_efc))),
    }
    rates = {}
    if env.device.type == "cuda":
        for name, (ncon, nefc) in sizes.items():
            rates[name] = round(raw_rate(engine, ncon, nefc, env.cfg.decimation, args.launches))
    fastest = max(rates.values()) if rates else None
    result = {
        "benchmark": "buffers_gpu", "task": "humanoid-walk", "num_envs": args.num_envs,
        "device": torch.cuda.get_device_name() if env.device.type == "cuda" else "cpu",
        "rollout_steps": args.steps, "peak_contacts_per_world": peak_con,
        "peak_constraint_rows_per_world": peak_efc,
        "sizes": {k: {"nconmax": c, "njmax": j, "physics_steps_per_s": rates.get(k)} for k, (c, j) in sizes.items()},
        "ratio": None if fastest is None else round(rates["engine"] / fastest, 3),
        "versions": {"mujoco_warp": mjw.__version__ if hasattr(mjw, "__version__") else "4.0.0",
                     "warp": wp.config.version, "torch": torch.__version__},
    }
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
