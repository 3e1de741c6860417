"""Seconds per evaluation (``ambulo eval``: 100 episodes of 20 s) on a GPU, eager vs replayed as a CUDA graph.

An evaluation runs 100 worlds for 1,000 policy steps; at that size a GPU step is bound by launching
its hundreds of small kernels (MuJoCo Warp's solver, the task's torch terms), not by running them,
and ``ambulo train --eval-every`` pays it at every evaluation (about 40 % of a time-to-walk run on an
H200 in session 11: 60-68 s of 2.6-2.8 min). ``RLEnv.use_cuda_graph`` replays the step as one graph.
Both sides run the shipped humanoid-walk policy through ``run_episodes`` (what ``ambulo eval`` and
the periodic evaluation run) from the same seed; the metrics of the two are printed side by side.

The ceiling is the physics alone: raw ``mujoco_warp.step`` of the task's model at the same number of
worlds, free running in a CUDA graph (``time_to_walk.ceiling``), as seconds for the evaluation's
env steps; ``ratio`` = that / the graph evaluation's seconds.

    python benchmarks/eval_gpu.py                     # cuda, 100 episodes of 20 s
    python benchmarks/eval_gpu.py --episode-length-s 2 --device cpu   # the CPU engine, eager only

Ends with one ``RESULT {json}`` line.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import torch

import ambulo.envs
from ambulo.engine.gpu import synchronize
from ambulo.policies.shipped import load_policy
from ambulo.rl.evaluate import run_episodes
from ambulo.rl.vecenv import RslRlVecEnv

TASK = "humanoid-walk"
METRICS = ("fall_rate", "mean_abs_vel_error_m_s", "mean_abs_yaw_rate_error_rad_s", "mean_return")


def timed_eval(env, policy) -> tuple[float, dict]:
    synchronize(env.device)
    start = time.perf_counter()
    result = run_episodes(env, RslRlVecEnv(env), policy, ambulo.envs.spec(TASK))
    synchronize(env.device)
    return time.perf_counter() - start, {k: result[k] for k in METRICS if k in result}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--device", default="cuda")
    p.add_argument("--num-episodes", type=int, default=100)
    p.add_argument("--episode-length-s", type=float, default=20.0)
    p.add_argument("--seed", type=int, default=12345)
    args = p.parse_args()
    shipped = load_policy(TASK)

    def policy(obs):
        return shipped(obs["policy"])

    def make(graph: bool, seconds: float):
        env = ambulo.envs.make(TASK, num_envs=args.num_episodes, device=args.device, seed=args.seed, play=True,
                               episode_length_s=seconds)
        return env, (env.use_cuda_graph() if graph else False)

    warm, _ = make(False, 1.0)  # loads (or compiles) the kernels outside the timed runs
    timed_eval(warm, policy)
    warm.close()
    eager, _ = make(False, args.episode_length_s)
    eager_s, eager_metrics = timed_eval(eager, policy)
    eager.close()
    print(f"eager: {eager_s:.2f} s {eager_metrics}", flush=True)  # kept if a time limit cuts the rest
    steps = eager.max_episode_length
    result = {"benchmark": "eval_gpu", "task": TASK, "device": str(eager.device),
              "gpu": torch.cuda.get_device_name() if eager.device.type == "cuda" else None,
              "num_episodes": args.num_episodes, "episode_length_s": args.episode_length_s, "steps": steps,
              "eager_s": round(eager_s, 3), "eager_metrics": eager_metrics}
    graphed, on = make(True, args.episode_length_s)
    if on:
        fresh = graphed.generator.get_state()
        first_s, first_metrics = timed_eval(graphed, policy)  # the capture happens in here
        print(f"graph, first (with the capture): {first_s:.2f} s {first_metrics}", flush=True)
        graphed.generator.set_state(fresh)  # as the periodic evaluation restarts each one
        again_s, again_metrics = timed_eval(graphed, policy)  # a later evaluation of the same env
        sys.path.insert(0, str(Path(__file__).parent))
        from time_to_walk import ceiling

        raw = ceiling(TASK, args.num_episodes, args.device, seconds=3.0)
        raw_s = steps * args.num_episodes / raw["raw_env_steps_per_s"]
        result.update({"graph_first_s": round(first_s, 3), "graph_s": round(again_s, 3),
                       "graph_metrics": first_metrics, "graph_again_metrics": again_metrics,
                       "speedup": round(eager_s / again_s, 2), "raw_physics_s": round(raw_s, 3),
                       "ratio": round(raw_s / again_s, 3)})
        print(f"{TASK} eval, {args.num_episodes} worlds x {steps} steps: eager {eager_s:.2f} s, graph {again_s:.2f} s "
              f"(first, with the capture, {first_s:.2f} s), raw physics {raw_s:.2f} s")
    else:
        print(f"{TASK} eval on {eager.device}: {eager_s:.2f} s eager (no CUDA graph off CUDA)")
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
