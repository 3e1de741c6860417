"""Object goals ("walk to the chair") on seeded apartments: success, SPL, distance and detection quality.

    python benchmarks/object_nav.py [--episodes 50] [--first-seed 0] [--modes oracle,full]
                                    [--workers 2] [--out out/bench_object_nav] [--ceiling]
                                    [--detector model.onnx]

Per mode, ``--episodes`` episodes on ``apartment(seed)`` for seeds ``first_seed ..`` (the shipped
detector was trained on apartments 1000-1079, so seeds 0-999 are apartments it never saw), start
drawn with episode seed 0 and the object class drawn among those present with no instance within
2 m of the start (``navigation.object_episode``). One process per episode task (pool of
``--workers``), torch/OpenCV on one thread; each episode's JSON is written under
``<out>/<group>/`` as it finishes and a rerun skips those that exist.

The ceiling (``--ceiling``): the same episodes with the object's true place given (no detector, no
search: ``known_object``): the walk to and facing of the object alone. ``ratio_to_ceiling`` is the
searched SPL over that ceiling's SPL (same mode, same episodes).

Prints a table and ``RESULT {json}``: per group, success, SPL, median distance to the object at the
end, falls, the localized object's precision (share of episodes that localized an object whose
point lies within 0.5 m of a true instance of the class), confirmed-track precision, simulated time
and wall time per episode, episodes per minute.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import time
from pathlib import Path

import numpy as np


def _episode(task: tuple) -> dict:
    seed, mode, known, detector, out_file = task
    from ambulo.navigation.benchmark import EpisodeSpec, episode_cfg, pin_threads
    from ambulo.navigation.object_episode import ObjectEpisodeCfg, run_object_episode

    pin_threads()
    spec = EpisodeSpec(seed, 0, mode, "policy", False)
    base = episode_cfg(spec)
    world = base.world if mode == "full" else type(base.world)(**{**base.world.__dict__, "record_gyro": False})
    cfg = ObjectEpisodeCfg(navigator=type(base.navigator)(**{**base.navigator.__dict__, "time_limit_s": 60.0}),
                           world=world)
    det = None
    if detector and not known:
        from ambulo.detection import Detector

        det = Detector(detector, score_threshold=cfg.search.score_threshold)
    try:
        result = run_object_episode(seed, 0, None, cfg, detector=det, known_object=known)
    except Exception as err:  # an episode's crash is a result, not the benchmark's end
        result = {"apartment_seed": seed, "mode": mode, "known_object": known, "error": repr(err), "success": False,
                  "spl": 0.0, "status": "error"}
    Path(out_file).write_text(json.dumps(result, default=float))
    return result


def summarize(results: list[dict]) -> dict:
    ok = [r for r in results if "error" not in r]
    localized = [r for r in ok if r.get("localized_correct") is not None]
    tracks = sum(r.get("confirmed_tracks", 0) for r in ok)
    return {
        "episodes": len(results), "errors": len(results) - len(ok),
        "success": float(np.mean([r["success"] for r in results])) if results else 0.0,
        "spl": float(np.mean([r["spl"] for r in results])) if results else 0.0,
        "distance_to_object_m_median": float(np.median([r["distance_to_object_m"] for r in ok])) if ok else None,
        "fell": float(np.mean([r["fell"] for r in ok])) if ok else None,
        "localized": len(localized),
        "localized_precision": float(np.mean([r["localized_correct"] for r in localized])) if localized else None,
        "track_precision": sum(r.get("correct_tracks", 0) for r in ok) / tracks if tracks else None,
        "time_s_mean": float(np.mean([r["time_s"] for r in ok])) if ok else None,
        "wall_s_mean": float(np.mean([r["wall_s"] for r in ok])) if ok else None,
        "statuses": {s: sum(r["status"] == s for r in results) for s in sorted({r["status"] for r in results})},
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--modes", default="oracle,full")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default="out/bench_object_nav")
    ap.add_argument("--ceiling", action="store_true", help="also the known-object episodes (no detection, no search)")
    ap.add_argument("--detector", default=None, help="ONNX detector (default: the shipped one)")
    ap.add_argument("--summarize", action="store_true",
                    help="run nothing: summarize the episodes already under --out (after a run was cut short)")
    args = ap.parse_args()
    from ambulo.navigation.object_episode import DETECTOR_PATH

    detector = str(args.detector or DETECTOR_PATH)
    load0 = os.getloadavg()[0]
    groups = [(mode, known) for mode in args.modes.split(",") for known in ((False, True) if args.ceiling else (False,))]
    tasks, files = [], {}
    for mode, known in groups:
        folder = Path(args.out) / f"{mode}{'_known' if known else ''}"
        folder.mkdir(parents=True, exist_ok=True)
        for i in range(args.episodes):
            seed = args.first_seed + i
            f = folder / f"apartment_{seed:04d}.json"
            if args.summarize and not f.exists():
                continue
            files.setdefault((mode, known), []).append(f)
            if not f.exists() and not args.summarize:
                tasks.append((seed, mode, known, detector, str(f)))
    t0 = time.perf_counter()
    if tasks:
        with mp.get_context("spawn").Pool(args.workers, maxtasksperchild=1) as pool:
            for r in pool.imap_unordered(_episode, tasks):
                print(f"{r['mode']}{' known' if r.get('known_object') else ''} apartment {r['apartment_seed']}: "
                      f"{r['status']} success={r['success']} spl={r['spl']:.2f} "
                      f"d={r.get('distance_to_object_m', float('nan')):.2f} m {r.get('label', '')}", flush=True)
    wall = time.perf_counter() - t0
    summary = {}
    for (mode, known), fs in files.items():
        summary[f"{mode}{'/known' if known else ''}"] = summarize([json.loads(f.read_text()) for f in fs])
    print(f"{'group':14s} {'n':>4s} {'success':>8s} {'SPL':>6s} {'d_med':>6s} {'loc_prec':>8s} {'trk_prec':>8s} {'wall_s':>7s}")
    for name, s in summary.items():
        fmt = lambda v, spec: "-" if v is None else format(v, spec)
        print(f"{name:14s} {s['episodes']:4d} {s['success']:8.2f} {s['spl']:6.2f} {fmt(s['distance_to_object_m_median'], '6.2f')} "
              f"{fmt(s['localized_precision'], '8.2f')} {fmt(s['track_precision'], '8.2f')} {fmt(s['wall_s_mean'], '7.1f')}")
    ratio = {m: summary[m]["spl"] / summary[f"{m}/known"]["spl"]
             for m in args.modes.split(",") if f"{m}/known" in summary and summary[f"{m}/known"]["spl"] > 0}
    print("RESULT " + json.dumps({"groups": summary, "ratio_to_ceiling": ratio, "detector": detector,
                                  "episodes_per_min": len(tasks) / wall * 60 if tasks else None,
                                  "load_start": load0, "load_end": os.getloadavg()[0]}, default=float))


if __name__ == "__main__":
    main()
