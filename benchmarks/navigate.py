"""The autonomous navigator on seeded apartments: success, SPL and costs per mode.

    python benchmarks/navigate.py [--episodes 100] [--modes oracle,mapping,full] [--walkers policy]
                                  [--randomize] [--workers 2] [--out out/bench_navigate] [--first-seed 0]
                                  [--ceiling-every 5] [--perception-device cpu|cuda]

Runs ``--episodes`` episodes per mode and walker on ``apartment(seed)`` for seeds
``first_seed .. first_seed + N - 1`` (the tests use seeds >= 1000, so these are held out), start and
goal drawn by ``metrics.run_episode`` with episode seed 0 (geodesic 3-8 m, time limit 30 s + 6 s per
metre). ``--randomize`` adds domain randomization (friction, masses, lights, colours, pushes,
sensor noise); ``--both`` runs each group with and without it. The work is
``navigation.benchmark.run_benchmark`` (the code ``ambulo navigate --episodes`` runs): a process
pool, one episode per task, each episode's JSON written under ``<out>/episodes`` as it finishes,
so a killed run resumes where it stopped when started again with the same ``--out``.

``--perception-device cuda``: full mode's TSDF and the odometry's map, rigidity check and pose
refinement run on the GPU (all workers share it); ORB, its matching and PnP stay on each worker's
core (``navigation.benchmark.with_perception_device``).

The ceiling: every ``--ceiling-every``-th episode of a group (0: none) is followed, in its worker,
by the same robot and scene stepped with physics and the walking policy only (no camera, VO,
mapping or planning; ``navigation.ceiling``) for the episode's simulated time, so the episodes'
simulated/wall ratio is compared with the fastest the walking itself allows on this machine at
this load.

Prints a table and ``RESULT {json}``: per group (mode/walker[/rand]) success, SPL, fall rate,
collisions per episode, stuck rate, p95 replan ms, simulated/wall time, the ceiling's simulated/wall
time and the episodes' share of it (``of_ceiling``, also in ``ratio_to_ceiling``), episodes per
minute (of the episodes run now), plus the load average at the start and the end.
"""

from __future__ import annotations

import argparse
import json
import os
import time

from ambulo.navigation.benchmark import EpisodeSpec, format_table, run_benchmark, with_perception_device


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, default=100)
    ap.add_argument("--modes", default="oracle,mapping,full")
    ap.add_argument("--walkers", default="policy")
    ap.add_argument("--randomize", action="store_true", help="randomized episodes only")
    ap.add_argument("--both", action="store_true", help="nominal and randomized episodes")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--out", default="out/bench_navigate")
    ap.add_argument("--ceiling-every", type=int, default=5,
                    help="measure the physics+policy ceiling after every k-th episode of a group (0: never)")
    ap.add_argument("--perception-device", default="cpu",
                    help="torch device of full mode's TSDF and odometry map/refinement, e.g. cuda (ORB stays on the host)")
    args = ap.parse_args()
    base = with_perception_device(args.perception_device)
    randomize = (False, True) if args.both else (args.randomize,)
    specs = [EpisodeSpec(args.first_seed + i, 0, mode, walker, rand)
             for walker in args.walkers.split(",") for rand in randomize for mode in args.modes.split(",")
             for i in range(args.episodes)]
    load_start = os.getloadavg()[0]
    t0 = time.perf_counter()
    run = run_benchmark(specs, args.out, workers=args.workers, ceiling_every=args.ceiling_every, base=base)
    print(format_table(run.summary))
    print("RESULT " + json.dumps({
        "benchmark": "navigate", "episodes_per_group": args.episodes, "workers": args.workers,
        "first_seed": args.first_seed, "perception_device": args.perception_device, "resumed": run.resumed, "wall_s": time.perf_counter() - t0,
        "load_start": load_start, "load_end": os.getloadavg()[0], "cpus": os.cpu_count(),
        "ratio_to_ceiling": {label: s["of_ceiling"] for label, s in run.summary.items()},
        "groups": run.summary}))


if __name__ == "__main__":
    main()
