"""Time to walk: minutes from `ambulo train` starting to the first checkpoint that walks.

For each seed, runs

    python -m ambulo.cli train TASK --device DEV --seed S --eval-every K --stop-at-criterion

in its own process (``--parallel`` at a time: several on one GPU share it, which the result
says), and reads the run's ``time_to_criterion.json``: wall-clock from the process start
(imports, env build, kernel compile and every evaluation included) to the evaluation that met
the task's criterion (humanoid-walk's ``walks``: fall rate <= 5 %, mean velocity error <= 0.2
m/s over 100 episodes of 20 s) on the training device and then, for the same checkpoint, on the
CPU engine (``ambulo.rl.periodic_eval``: a success on the GPU engine alone does not stop the run),
with both evaluations' output. A run that has not walked by
``--max-minutes`` is stopped with SIGINT (it saves) and counts as not reached. Each seed's entry
also splits its minutes: ``eval_s_included`` (the evaluations), the iterations' collect and learn
times (``metrics.csv``) and ``startup_s``, the rest (imports, env build, the kernel compile; with
``--eval-async``, counted to the judged checkpoint's save, and ``verdict_lag_s`` from there to the
verdict): what
a warm or cold kernel cache, or a machine's earlier runs, change.

The ceiling is the physics alone: raw ``mujoco_warp.step`` of the task's model at the same
number of worlds, free running in a CUDA graph (``benchmarks/env_gpu.py``'s ``RawWarp``), in
env-steps/s (physics steps / decimation); ``ratio`` = training env-steps/s (collection and PPO
update, from metrics.csv) / that ceiling: the share of the GPU's physics speed that reaches
learning.

    python benchmarks/time_to_walk.py --task humanoid-walk --seeds 0,1,2 --device cuda \
        --parallel 3 --max-minutes 9 --out /tmp/ttw
    python benchmarks/time_to_walk.py --task cartpole --seeds 0 --device cpu --num-envs 256 \
        --eval-every 10 --max-minutes 2 --no-ceiling   # a smoke run on the CPU

``--algo`` picks the learner (``ppo``, ``fast-sac``, ``fast-td3``; see ``ambulo.rl.offpolicy``);
a comma list runs each on the same seeds, one after the other, and the result holds each one's
numbers under ``algos`` plus ``speedup_vs_ppo`` (PPO's median minutes / the algorithm's) and
``env_steps_ratio_vs_ppo`` (its median env steps to the criterion / PPO's). An off-policy
iteration is ``num_steps_per_env`` (8) env steps and their updates, a PPO one 24 steps: give each
its ``--eval-every`` as ``ALGO=K`` pairs, e.g. ``--eval-every ppo=25,fast-sac=100``.

    python benchmarks/time_to_walk.py --task cartpole --algo ppo,fast-sac --seeds 0,1,2 --device cpu \
        --eval-every ppo=10,fast-sac=25 --max-minutes 10 --no-ceiling --out /tmp/ttw-cartpole

Ends with one ``RESULT {json}`` line.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import json
import os
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path


def child_visible_devices(gpus: list[str], inherited: str | None) -> str:
    """The CUDA_VISIBLE_DEVICES of a run given ``gpus`` (--gpu-ids): ids of the GPUs *this* process
    sees. Under an inherited mask (``CUDA_VISIBLE_DEVICES=1 python time_to_walk.py --gpu-ids 0``)
    id 0 is physical GPU 1; setting the child's mask to the raw id would put the run on GPU 0,
    beside whatever runs there (session 21 lost half a GPU's speed that way)."""
    if not inherited:
        return ",".join(gpus)
    seen = [d.strip() for d in inherited.split(",") if d.strip()]
    beyond = [g for g in gpus if not g.isdigit() or int(g) >= len(seen)]
    if beyond:
        raise SystemExit(f"--gpu-ids {','.join(beyond)}: CUDA_VISIBLE_DEVICES={inherited} leaves {len(seen)} GPU(s) "
                         f"visible, numbered 0..{len(seen) - 1}; give ids in that range or unset the variable")
    return ",".join(seen[int(g)] for g in gpus)


def launch(args, algo: str, seed: int, out: Path, gpus: list[str]) -> tuple[subprocess.Popen, Path]:
    """Start one seed's training run on ``gpus`` (CUDA ids; empty: the device as given), through
    torchrun with one rank per GPU when there are several."""
    root = out / f"seed{seed}"
    root.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ)
    if gpus:
        env["CUDA_VISIBLE_DEVICES"] = child_visible_devices(gpus, os.environ.get("CUDA_VISIBLE_DEVICES"))
    ranks = len(gpus) if len(gpus) > 1 else 1
    prefix = ([sys.executable, "-m", "torch.distributed.run", "--standalone", f"--nproc-per-node={ranks}"]
              if ranks > 1 else [sys.executable])
    cmd = [*prefix, "-m", "ambulo.cli", "train", args.task, "--device", args.device,
           "--seed", str(seed), "--eval-every", str(eval_every(args.eval_every, algo)),
           *([] if args.keep_training else ["--stop-at-criterion"]), *(["--eval-async"] if args.eval_async else []),
           "--max-iterations", str(args.max_iterations), "--log-root", str(root)]
    if args.num_envs:
        cmd += ["--num-envs", str(args.num_envs)]
    for pair in args.env_cfg or []:
        cmd += ["--env-cfg", pair]
    if algo != "ppo":
        cmd += ["--algo", algo]
        for pair in args.algo_cfg or []:
            cmd += ["--algo-cfg", pair]
    else:
        for pair in args.ppo_cfg or []:
            cmd += ["--ppo-cfg", pair]
    log = open(root / "train.log", "w")
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
    return proc, root


def eval_every(text: str, algo: str) -> int:
    """``--eval-every``: one K for every algorithm, or ``ALGO=K`` pairs."""
    if "=" not in text:
        return int(text)
    pairs = dict(pair.split("=") for pair in text.split(","))
    if algo not in pairs:
        raise SystemExit(f"--eval-every {text} gives no K for {algo}")
    return int(pairs[algo])


def run_summary(root: Path) -> dict:
    """What one seed's run folder says: time to the criterion and training throughput."""
    runs = sorted(root.glob("*/*/run.json"))
    if not runs:
        return {"reached": False, "error": (root / "train.log").read_text()[-2000:]}
    run = runs[-1].parent
    out: dict = {"run": str(run), "reached": False}
    reached = run / "time_to_criterion.json"
    wall_s = None
    if reached.is_file():
        info = json.loads(reached.read_text())
        wall_s = info["wall_s"]
        out.update(reached=True, minutes=round(info["wall_s"] / 60, 2), iteration=info["iteration"],
                   env_steps=info["env_steps"], eval=info["eval"], eval_cpu_engine=info.get("eval_cpu_engine"),
                   eval_s_included=info["eval_s_included"])
        if info.get("eval_async"):  # judged in the background: the verdict came this long after the save
            wall_s = info["checkpoint_wall_s"]  # training went on meanwhile: start-up counts to the save
            out.update(eval_async=True, verdict_lag_s=round(info["wall_s"] - wall_s, 1))
    rows = list(csv.DictReader(open(run / "metrics.csv"))) if (run / "metrics.csv").is_file() else []
    if rows:
        spans = [float(r["collect_s"]) + float(r["learn_s"]) for r in rows[1:]] or [1e-9]
        steps = int(rows[-1]["env_steps"]) - int(rows[0]["env_steps"])
        out["iterations"] = len(rows)
        out["train_env_steps_per_s"] = round(steps / max(sum(spans), 1e-9))
        out["collect_s_per_it"] = round(statistics.median(float(r["collect_s"]) for r in rows), 3)
        out["learn_s_per_it"] = round(statistics.median(float(r["learn_s"]) for r in rows), 3)
        if out["reached"]:  # what was neither training nor evaluating: imports, env build, kernel compile
            trained = sum(float(r["collect_s"]) + float(r["learn_s"]) for r in rows
                          if int(r["iteration"]) <= out["iteration"])
            out["startup_s"] = round(wall_s - out["eval_s_included"] - trained, 1)
    evals = run / "evals.csv"
    if evals.is_file():
        out["evals"] = [dict(r) for r in csv.DictReader(open(evals))]
    return out


def ceiling(task: str, num_envs: int, device: str, seconds: float = 5.0) -> dict:
    """Raw MuJoCo Warp env-steps/s of ``task``'s model at ``num_envs`` worlds (see the docstring)."""
    sys.path.insert(0, str(Path(__file__).parent))
    from env_gpu import RawWarp

    import ambulo.envs
    from ambulo.engine.gpu import synchronize

    env = ambulo.envs.make(task, num_envs=num_envs, device=device, seed=0)
    raw = RawWarp(env.engine, env.cfg.decimation)
    for _ in range(10):
        raw.launch()
    synchronize(raw.device)
    launches, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        for _ in range(20):
            raw.launch()
        synchronize(raw.device)
        launches += 20
    rate = launches * num_envs / (time.perf_counter() - start)
    return {"raw_env_steps_per_s": round(rate), "num_envs": num_envs}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--task", default="humanoid-walk")
    p.add_argument("--seeds", default="0,1,2")
    p.add_argument("--device", default="cuda")
    p.add_argument("--num-envs", type=int)
    p.add_argument("--algo", default="ppo", help="ppo, fast-sac or fast-td3, or a comma list of them")
    p.add_argument("--eval-every", default="25", help="K, or ALGO=K pairs (ppo=25,fast-sac=100)")
    p.add_argument("--max-iterations", type=int, default=100000)
    p.add_argument("--max-minutes", type=float, default=9.0)
    p.add_argument("--parallel", type=int, default=1, help="runs at once (on one device, or each on its "
                                                            "own GPUs with --gpu-ids)")
    p.add_argument("--gpu-ids", default="", help="CUDA ids the runs share out, e.g. 0,1,2,3 (default: "
                                                 "every run on --device)")
    p.add_argument("--gpus-per-run", type=int, default=1,
                   help="GPUs per run from --gpu-ids: more than 1 trains data-parallel through torchrun")
    p.add_argument("--env-cfg", action="append")
    p.add_argument("--ppo-cfg", action="append")
    p.add_argument("--algo-cfg", action="append", help="the off-policy algorithms' settings (OffPolicyCfg)")
    p.add_argument("--out", default="/tmp/ambulo-time-to-walk")
    p.add_argument("--eval-async", action="store_true",
                   help="evaluate in a worker process while training goes on (ambulo train --eval-async)")
    p.add_argument("--no-ceiling", action="store_true")
    p.add_argument("--keep-training", action="store_true",
                   help="train on to --max-minutes after the criterion (for the best policy); the "
                        "time to the criterion is recorded all the same")
    args = p.parse_args()
    algos = [a for a in args.algo.split(",") if a]
    results = {algo: run_algo(args, algo, Path(args.out) / algo if len(algos) > 1 else Path(args.out))
               for algo in algos}
    if len(algos) == 1:
        result = results[algos[0]]
    else:
        result = {"benchmark": "time_to_walk", "task": args.task, "device": args.device,
                  "date": datetime.date.today().isoformat(), "algos": results}
        ppo = results.get("ppo")
        for algo, res in results.items():
            if algo == "ppo" or ppo is None or not ppo["minutes_median"] or not res["minutes_median"]:
                continue
            res["speedup_vs_ppo"] = round(ppo["minutes_median"] / res["minutes_median"], 3)
            res["env_steps_ratio_vs_ppo"] = round(res["env_steps_median"] / ppo["env_steps_median"], 4)
    print("RESULT " + json.dumps(result))


def run_algo(args, algo: str, out: Path) -> dict:
    """Every seed of ``algo``; its result (``RESULT``'s fields)."""
    seeds = [int(s) for s in args.seeds.split(",")]
    free_gpus = [g for g in args.gpu_ids.split(",") if g]
    child_visible_devices(free_gpus, os.environ.get("CUDA_VISIBLE_DEVICES"))  # refuse bad ids before any run starts
    if free_gpus and len(free_gpus) < args.gpus_per_run:
        raise SystemExit(f"--gpus-per-run {args.gpus_per_run} needs at least that many --gpu-ids (got {free_gpus})")
    pending, running, done, held = list(seeds), {}, {}, {}
    while pending or running:
        while pending and len(running) < args.parallel:
            if args.gpu_ids and len(free_gpus) < args.gpus_per_run:
                break
            seed = pending.pop(0)
            held[seed] = [free_gpus.pop(0) for _ in range(args.gpus_per_run)] if args.gpu_ids else []
            running[seed] = (*launch(args, algo, seed, out, held[seed]), time.monotonic())
        time.sleep(2.0)
        for seed, (proc, root, began) in list(running.items()):
            if proc.poll() is None and time.monotonic() - began > args.max_minutes * 60:
                proc.send_signal(signal.SIGINT)  # it saves the iteration under way
                try:
                    proc.wait(timeout=60)
                except subprocess.TimeoutExpired:
                    proc.kill()
            if proc.poll() is not None:
                done[seed] = run_summary(root)
                del running[seed]
                free_gpus.extend(held.pop(seed))
                s = done[seed]
                print(f"{algo} seed {seed}: " + (f"meets the criterion after {s['minutes']} min (iteration "
                                                 f"{s['iteration']}, {s['env_steps']:,} env steps)"
                                                 if s["reached"] else "did not reach the criterion"), flush=True)
    reached = [done[s]["minutes"] for s in seeds if done[s]["reached"]]
    steps = [done[s]["env_steps"] for s in seeds if done[s]["reached"]]
    rates = [done[s]["train_env_steps_per_s"] for s in seeds if "train_env_steps_per_s" in done[s]]
    result = {
        "benchmark": "time_to_walk", "task": args.task, "algo": algo, "device": args.device,
        "date": datetime.date.today().isoformat(), "seeds": seeds, "parallel_runs_per_device": 1 if args.gpu_ids else args.parallel,
        "gpus_per_run": args.gpus_per_run if args.gpu_ids else 1,
        "reached": f"{len(reached)}/{len(seeds)}",
        "minutes_median": statistics.median(reached) if reached else None,
        "minutes_min": min(reached) if reached else None,
        "minutes_max": max(reached) if reached else None,
        "env_steps_median": statistics.median(steps) if steps else None,
        "train_env_steps_per_s_median": statistics.median(rates) if rates else None,
        "runs": {str(s): {k: v for k, v in done[s].items() if k != "evals"} for s in seeds},
    }
    if args.device.startswith("cuda"):
        import torch

        result["gpu"] = torch.cuda.get_device_name(0)
    if not args.no_ceiling:
        run_file = json.loads(next(out.glob("seed*/*/*/run.json")).read_text())
        num_envs = args.num_envs or run_file.get("ppo", run_file.get("offpolicy"))["num_envs"]
        result["ceiling"] = ceiling(args.task, num_envs, args.device)
        if rates:
            result["ratio"] = round(statistics.median(rates) / result["ceiling"]["raw_env_steps_per_s"], 3)
    (out / "evals.json").write_text(json.dumps({str(s): done[s].get("evals", []) for s in seeds}, indent=1))
    return result


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    main()
