"""What building more tile kinds as static boxes costs (``TerrainCfg.box_kinds``): box count, build
time and env step time of a terrain task, the task's default against ``--box-kinds``.

Why: a box tile gives a resting sphere one contact in both engines (``scenes.terrain.boxes``), but
every box is a geom in every world: MuJoCo C places and sweeps it each physics step, MuJoCo Warp's
broadphase pairs it with every moving geom. Stepping stones as boxes are ~1,400 more boxes on
humanoid-rough's grid; this measures what they cost before anyone turns them on.

The two variants are built in one process and stepped alternately (``--rounds`` of ``--steps``
random-action env steps each, after a warm-up), so a load change on a shared machine hits both;
the median round is reported. ``--engine warp`` on a machine without CUDA runs MuJoCo Warp on
Warp's CPU device (its first build compiles the kernels, minutes).

    python benchmarks/terrain_box_cost.py --engine mujoco
    python benchmarks/terrain_box_cost.py --engine warp --steps 25 --rounds 4

Ends with one ``RESULT {json}`` line; ``step_ratio`` = the option's median ms a step over the default's.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import mujoco
import torch

import ambulo.envs as envs
from ambulo.scenes.terrain import add_terrain, generate, terrain_boxes

STONES_AS_BOXES = "flat,stairs_up,stairs_down,stepping_stones"


def build_cost(cfg, repeats: int = 3) -> dict:
    """Box count and seconds (the best of ``repeats``: the first build in a process is slower) to
    generate, to build the boxes, to add the terrain to a spec and compile it."""
    runs = [_build_once(cfg) for _ in range(repeats)]
    return {k: min(r[k] for r in runs) for k in runs[0]}


def _build_once(cfg) -> dict:
    t0 = time.perf_counter()
    grid = generate(cfg)
    t1 = time.perf_counter()
    boxes = terrain_boxes(grid)
    t2 = time.perf_counter()
    spec = mujoco.MjSpec()
    add_terrain(spec, grid)  # builds the boxes again, and the hfield
    spec.compile()
    t3 = time.perf_counter()
    return {"boxes": len(boxes.top_m), "generate_s": round(t1 - t0, 3), "terrain_boxes_s": round(t2 - t1, 3),
            "add_terrain_compile_s": round(t3 - t2, 3)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--task", default="humanoid-rough", help="a terrain task")
    p.add_argument("--box-kinds", default=STONES_AS_BOXES, help="the option's terrain.box_kinds, comma-separated")
    p.add_argument("--engine", default="mujoco", choices=("mujoco", "warp"))
    p.add_argument("--device", default="cpu", help="cpu (with --engine warp: Warp's CPU device) or cuda[:N]")
    p.add_argument("--num-envs", type=int, default=16)
    p.add_argument("--steps", type=int, default=50, help="env steps a round")
    p.add_argument("--rounds", type=int, default=6)
    p.add_argument("--warmup", type=int, default=5)
    args = p.parse_args()
    option = {"terrain.box_kinds": tuple(k for k in args.box_kinds.split(",") if k)}
    cfgs = {"default": envs.make_cfg(args.task), "option": envs.make_cfg(args.task, **option)}
    result = {"task": args.task, "engine": args.engine, "device": args.device, "num_envs": args.num_envs,
              "default_box_kinds": list(cfgs["default"].terrain.box_kinds), "option_box_kinds": list(option.values())[0],
              "build": {k: build_cost(c.terrain) for k, c in cfgs.items()}}
    variants = {k: envs.make(args.task, num_envs=args.num_envs, device=args.device, seed=0, engine=args.engine,
                             **({} if k == "default" else option)) for k in cfgs}
    generator = torch.Generator(device=args.device).manual_seed(0)

    def run(env, n: int) -> float:
        """Seconds for ``n`` random-action env steps (CUDA bracketed by synchronizations)."""
        if env.device.type == "cuda":
            torch.cuda.synchronize(env.device)
        start = time.perf_counter()
        for _ in range(n):
            env.step(torch.rand(env.num_envs, env.num_actions, generator=generator, device=env.device) * 2 - 1)
        if env.device.type == "cuda":
            torch.cuda.synchronize(env.device)
        return time.perf_counter() - start

    for env in variants.values():
        run(env, args.warmup)
    ms = {k: [] for k in variants}
    for _ in range(args.rounds):  # alternate: a load change on a shared machine hits both
        for name, env in variants.items():
            ms[name].append(1e3 * run(env, args.steps) / args.steps)
    result["ms_per_env_step"] = {k: {"median": round(statistics.median(v), 2), "min": round(min(v), 2)}
                                 for k, v in ms.items()}
    result["step_ratio"] = round(result["ms_per_env_step"]["option"]["median"]
                                 / result["ms_per_env_step"]["default"]["median"], 3)
    for name in variants:
        b, s = result["build"][name], result["ms_per_env_step"][name]
        print(f"{name:8s} {b['boxes']:5d} boxes, built in {b['terrain_boxes_s']:.2f} s (+ spec and compile "
              f"{b['add_terrain_compile_s']:.2f} s); {s['median']:.2f} ms an env step of {args.num_envs} envs")
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
