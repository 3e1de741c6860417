"""An off-policy training iteration as ``ambulo train TASK --algo fast-sac`` runs it, per variant,
against what its two halves cost alone.

An iteration is ``num_steps_per_env`` env steps of every world, each followed by
``updates_per_step`` gradient updates. This builds the task's env and the real runner
(``OffPolicyRunner``, the settings of ``offpolicy_cfg``) once per variant (``--modes``):

* ``base``: the defaults;
* ``envgraph``: the env step replayed as one CUDA graph (``EnvCfg.cuda_graph``; refused by tasks
  not graph-audited);
* ``overlap``: collection beside the updates on a second CUDA stream (``overlap_collect``);
* ``both``.

Each runs ``--warmup`` iterations (compiles, graph captures, the ring's first fill), then
``--iterations`` timed ones: ``s_per_it`` (device synchronized before and after). In the same run,
on the base variant's runner, the two halves alone: ``env_s_per_step`` (one collection step of
every world: actor, noise, env step, ring write) and ``updates_s_per_step`` (``updates_per_step``
updates), each over ``--iterations`` x ``num_steps_per_env`` steps. The ceilings:
``sequential_s_per_it`` = steps x (env + updates), what one stream can at best do, and
``overlap_ideal_s_per_it`` = steps x max(env, updates), what perfect overlap would give; each
variant's ``ratio`` is ``overlap_ideal_s_per_it / s_per_it`` (1.0: the halves fully hidden behind
each other). On the CPU nothing overlaps: the variants measure the bookkeeping.

Prints ``BENCH {json}`` per variant and one ``RESULT {json}``.

    python benchmarks/offpolicy_iteration.py --device cuda --task humanoid-walk
    python benchmarks/offpolicy_iteration.py --device cpu --task cartpole --num-envs 16 --iterations 4 \
        --warmup 3 --modes base,overlap      # a CPU smoke run
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

import torch

from ambulo import envs
from ambulo.rl.offpolicy import OffPolicyRunner, offpolicy_cfg
from ambulo.utils.overrides import apply_overrides

MODES = {"base": (False, False), "envgraph": (True, False), "overlap": (False, True), "both": (True, True)}
"""Variant -> (env step as a CUDA graph, overlap_collect)."""


def sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def build(args, mode: str) -> OffPolicyRunner:
    env_graph, overlap = MODES[mode]
    env = envs.make(args.task, num_envs=args.num_envs, device=args.device, seed=args.seed,
                    **({"cuda_graph": True} if env_graph else {}))
    cfg = apply_overrides(offpolicy_cfg(args.task, args.algo, num_envs=env.num_envs), args.algo_cfg or [])
    cfg = apply_overrides(cfg, [f"overlap_collect={str(overlap).lower()}"])  # the variant's, whatever --algo-cfg says
    torch.manual_seed(args.seed)
    return OffPolicyRunner(env, cfg, seed=args.seed)


def timed_learn(runner: OffPolicyRunner, iterations: int) -> float:
    """Seconds per iteration of ``runner.learn`` (the device synchronized around it)."""
    sync(runner.device)
    began = time.perf_counter()
    runner.learn(iterations)
    sync(runner.device)
    return (time.perf_counter() - began) / iterations


def halves(runner: OffPolicyRunner, steps: int) -> tuple[float, float]:
    """(collection s, updates s) per env step, each alone, on a runner past its warm-up."""
    sync(runner.device)
    began = time.perf_counter()
    for _ in range(steps):
        runner._collect()
    sync(runner.device)
    env_s = (time.perf_counter() - began) / steps
    began = time.perf_counter()
    for _ in range(steps):
        for _ in range(runner.cfg.updates_per_step):
            runner.alg.update_from(runner.ring, runner.generator)
    sync(runner.device)
    return env_s, (time.perf_counter() - began) / steps


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--task", default="humanoid-walk")
    p.add_argument("--algo", default="fast-sac")
    p.add_argument("--device", default="cuda")
    p.add_argument("--num-envs", type=int, help="default: the algorithm's task default")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--modes", default="base,envgraph,overlap,both")
    p.add_argument("--warmup", type=int, default=30, help="iterations before timing (past learning_starts)")
    p.add_argument("--iterations", type=int, default=100)
    p.add_argument("--algo-cfg", action="append", metavar="KEY=VALUE", help="OffPolicyCfg settings, as ambulo train's")
    args = p.parse_args()
    modes = [m for m in args.modes.split(",") if m]
    unknown = [m for m in modes if m not in MODES]
    if unknown:
        raise SystemExit(f"--modes {','.join(unknown)}: unknown; give some of {', '.join(MODES)}")
    if args.num_envs is None:
        args.num_envs = offpolicy_cfg(args.task, args.algo).num_envs
    out: dict = {"task": args.task, "algo": args.algo, "device": args.device, "num_envs": args.num_envs,
                 "torch": torch.__version__, "modes": {}}
    if args.device.startswith("cuda"):
        out["gpu"] = torch.cuda.get_device_name(torch.device(args.device))
    for mode in modes:
        began = time.perf_counter()
        runner = build(args, mode)
        runner.learn(args.warmup)
        setup_s = time.perf_counter() - began
        s_per_it = timed_learn(runner, args.iterations)
        row = {"mode": mode, "s_per_it": round(s_per_it, 5), "setup_s": round(setup_s, 1)}
        if mode == modes[0]:  # the halves, on a warmed-up runner of the first variant
            env_s, updates_s = halves(runner, args.iterations * runner.cfg.num_steps_per_env)
            steps = runner.cfg.num_steps_per_env
            out.update(steps_per_it=steps, updates_per_step=runner.cfg.updates_per_step, halves_of=mode,
                       env_s_per_step=round(env_s, 6), updates_s_per_step=round(updates_s, 6),
                       sequential_s_per_it=round(steps * (env_s + updates_s), 5),
                       overlap_ideal_s_per_it=round(steps * max(env_s, updates_s), 5))
        out["modes"][mode] = row
        runner.raw_env.close()
        print("BENCH " + json.dumps(row), flush=True)
    for row in out["modes"].values():
        row["ratio"] = round(out["overlap_ideal_s_per_it"] / row["s_per_it"], 3)
    print("RESULT " + json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
