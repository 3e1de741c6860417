"""Env-steps/s of humanoid-rough against humanoid-walk (flat), same engine, device and env count.

Issue 30's bar: rough-terrain env throughput >= 50 % of flat. Both tasks step random actions
(uniform in +-1) through ``env.step`` (physics, observations, rewards, resets); the flat task is
the ceiling. humanoid-rough is timed twice: as trained (the heightfield, the 187-point height scan,
transfer randomization with 0-20 ms action latency, which steps physics one step at a time) and
without action latency (one batched call per policy step, as the flat task), so the cost of the
terrain and of the latency show apart. Runs alternate (flat, rough, rough without latency, ...)
and the best of each is kept; CUDA timings are bracketed by synchronizations.

    python benchmarks/rough_terrain.py --device cuda --num-envs 4096 --steps 100
    python benchmarks/rough_terrain.py --num-envs 16 --steps 20          # CPU engine
    python benchmarks/rough_terrain.py --rough-set terrain.spacing_m=0.1  # a lever, on both rough variants
    python benchmarks/rough_terrain.py --engine warp --num-envs 16 --steps 20  # MuJoCo Warp, Warp's CPU device
    python benchmarks/rough_terrain.py --device cuda --broadphases nxn,sap_tile  # MuJoCo Warp's broadphases
    python benchmarks/rough_terrain.py --rough-set \
        "terrain.box_kinds=('flat','stairs_up','stairs_down','stepping_stones')"  # stones as boxes
    python benchmarks/rough_terrain.py --device cuda --num-envs 4096 --steps 100 --all-box-colliders  # and every geom on the boxes

humanoid-rough's boxes collide with the legs only (its default ``box_collider_bodies``,
``HUMANOID_BOX_COLLIDERS``: fewer candidate pairs for MuJoCo Warp's nxn broadphase).
``--all-box-colliders`` adds both rough variants again with every robot geom touching the boxes
(``box_collider_bodies=None``, the default before session 20), stepped alternately with the others
(``ratio_all_boxes``, ``ratio_all_boxes_no_latency``).

Ends with one ``RESULT {json}`` line: ``ratio`` = rough (as trained) / flat env-steps/s.
"""

from __future__ import annotations

import argparse
import ast
import json
import time

import torch

import ambulo.envs as envs

TARGET_RATIO = 0.5


def make(task: str, args, **overrides):
    engine = {} if args.engine is None else {"engine": args.engine}
    return envs.make(task, num_envs=args.num_envs, device=args.device, seed=0, **engine, **overrides)


def parse_override(item: str) -> tuple[str, object]:
    """``"key=value"`` -> (key, the value as a Python literal, else the text)."""
    key, sep, text = item.partition("=")
    if not sep or not key:
        raise SystemExit(f"--rough-set {item!r}: give KEY=VALUE, e.g. terrain.spacing_m=0.1")
    try:
        return key, ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return key, text


def steps_per_s(env, steps: int, warmup: int, generator: torch.Generator) -> float:
    def run(n):
        for _ in range(n):
            env.step(torch.rand(env.num_envs, env.num_actions, generator=generator, device=env.device) * 2 - 1)

    run(warmup)
    if env.device.type == "cuda":
        torch.cuda.synchronize(env.device)
    start = time.perf_counter()
    run(steps)
    if env.device.type == "cuda":
        torch.cuda.synchronize(env.device)
    return steps * env.num_envs / (time.perf_counter() - start)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--engine", choices=("mujoco", "warp"),
                        help="the physics engine of every variant (default: the device's; warp with --device cpu "
                             "is MuJoCo Warp on Warp's CPU device)")
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--warmup", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--rough-set", action="append", default=[], metavar="KEY=VALUE",
                        help="an envs.make override of both humanoid-rough variants (a Python literal value), "
                             "e.g. terrain.spacing_m=0.1 or sole_sphere_radius_m=None; repeatable")
    parser.add_argument("--broadphases", default="",
                        help="comma-separated PhysicsCfg.broadphase values (nxn, sap_tile, sap_segmented): one more "
                             "rough variant each, stepped alternately with the others in this process")
    parser.add_argument("--all-box-colliders", action="store_true",
                        help="also time both rough variants with every robot geom colliding with the terrain's boxes "
                             "(box_collider_bodies=None; the task's default is the legs only)")
    args = parser.parse_args()
    broadphases = [b for b in args.broadphases.split(",") if b]
    rough_set = dict(parse_override(item) for item in args.rough_set)
    generator = torch.Generator(device=args.device).manual_seed(0)
    variants = {
        "flat": make("humanoid-walk", args),
        "rough": make("humanoid-rough", args, **rough_set),
        "rough_no_latency": make("humanoid-rough", args, **rough_set, **{"transfer.action_latency_range_s": None}),
        **{f"rough_{b}": make("humanoid-rough", args, **{**rough_set, "physics.broadphase": b}) for b in broadphases},
    }
    if args.all_box_colliders:
        every = {"box_collider_bodies": None, **rough_set}
        variants["rough_all_boxes"] = make("humanoid-rough", args, **every)
        variants["rough_all_boxes_no_latency"] = make("humanoid-rough", args, **every,
                                                      **{"transfer.action_latency_range_s": None})
    best = dict.fromkeys(variants, 0.0)
    for _ in range(args.repeats):
        for name, env in variants.items():
            best[name] = max(best[name], steps_per_s(env, args.steps, args.warmup, generator))
    result = {"device": args.device, "engine": args.engine, "num_envs": args.num_envs, "steps": args.steps, "rough_set": args.rough_set,
              "env_steps_per_s": {k: round(v, 1) for k, v in best.items()},
              "ratio": round(best["rough"] / best["flat"], 3),
              "ratio_no_latency": round(best["rough_no_latency"] / best["flat"], 3),
              "target_ratio": TARGET_RATIO,
              **{f"ratio_{b}": round(best[f"rough_{b}"] / best["flat"], 3) for b in broadphases},
              **{f"ratio_{k[6:]}": round(best[k] / best["flat"], 3) for k in best if k.startswith("rough_all_boxes")}}
    for name, value in best.items():
        print(f"{name:22s} {value:12.1f} env-steps/s")
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
