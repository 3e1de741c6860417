"""What reducing MuJoCo C's heightfield contacts to Warp's costs the CPU engine (``engine.mujoco_hfield``).

The reduction wraps MuJoCo's collision function of every geom-heightfield pair (a numba-compiled C
callback; without numba a ctypes Python one that takes the GIL, ~4x slower on hfield tiles), so it
could slow the CPU engine's physics there. This steps humanoid-rough's play env on ``--kinds`` tiles
with a run's policy (``--run``; else zero actions, the default pose) for ``--steps`` env steps,
with the reduction (the task's default) and with MuJoCo's own contacts, alternating ``--repeats``
times and keeping the best of each, and reports env-steps/s. Ends with one ``RESULT {json}``.

    python benchmarks/hfield_reduce_cost.py --run <run>/model_1514.pt --num-envs 64
"""

from __future__ import annotations

import argparse
import json
import time

import torch

from ambulo import envs
from ambulo.rl import runs


def env_steps_per_s(args, info, run_dir, ckpt, as_warp: bool) -> float:
    overrides = {"terrain.kinds": tuple(args.kinds.split(",")), "mujoco_hfield_contacts_as_warp": as_warp}
    if info is not None:
        env = runs.make_env_for_run(info, num_envs=args.num_envs, seed=args.seed, play=True, device="cpu",
                                    engine="mujoco", **overrides)
        runner = runs.load_runner(run_dir, env, ckpt)
        policy, vec = runner.get_inference_policy(device="cpu"), runner.env
    else:
        env = envs.make("humanoid-rough", num_envs=args.num_envs, seed=args.seed, play=True, device="cpu",
                        engine="mujoco", **overrides)
        policy, vec = None, None
    obs = vec.reset() if vec is not None else env.reset()
    hold = torch.zeros(env.num_envs, env.num_actions)
    with torch.inference_mode():
        t0 = time.perf_counter()
        for _ in range(args.steps):
            if vec is not None:
                obs, *_ = vec.step(policy(obs))
            else:
                env.step(hold)
        seconds = time.perf_counter() - t0
    env.close()
    return args.num_envs * args.steps / seconds


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--run", help="a humanoid-rough run folder or checkpoint (its policy acts)")
    p.add_argument("--kinds", default="rough,slope_up,slope_down,stepping_stones")
    p.add_argument("--num-envs", type=int, default=64)
    p.add_argument("--steps", type=int, default=200)
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--seed", type=int, default=7)
    args = p.parse_args()
    info = run_dir = ckpt = None
    if args.run:
        run_dir, ckpt = runs.resolve_policy(args.run)
        info = runs.read_run_info(run_dir)
    best = {"own": 0.0, "warp": 0.0}
    for _ in range(args.repeats):
        for name in best:
            best[name] = max(best[name], env_steps_per_s(args, info, run_dir, ckpt, as_warp=name == "warp"))
    result = {"kinds": args.kinds, "num_envs": args.num_envs, "steps": args.steps, "policy": bool(args.run),
              "env_steps_per_s": {k: round(v, 1) for k, v in best.items()},
              "ratio": round(best["warp"] / best["own"], 3)}
    print(f"MuJoCo's own hfield contacts {best['own']:.0f} env-steps/s, reduced as Warp's {best['warp']:.0f} "
          f"(ratio {result['ratio']})")
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
