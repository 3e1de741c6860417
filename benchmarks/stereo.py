"""Stereo disparity: OpenCV's SGBM and block matcher (CPU) against the torch semi-global matcher
(``ambulo.perception.stereo.sgm``) on the Middlebury 2014 Motorcycle pair that scikit-image ships
(500x741, true disparities 7-60 px), all with the same 64-disparity search range.

    python benchmarks/stereo.py [--device cpu|cuda] [--repeats 5] [--paths 8] [--threads N]
                                [--aggregation both|auto|torch|warp]
    python benchmarks/stereo.py --save-pair out/motorcycle.npz   # for a machine without scikit-image
    python benchmarks/stereo.py --pair out/motorcycle.npz --device cuda

Accuracy against the ground truth over the pixels that have one: density (share with a
disparity), bad 2.0 (share of those off by more than 2 px) and the median |error|, px.
Time: median ms per pair over ``--repeats`` after one warm-up, grey conversion included; torch
takes and returns tensors on ``--device`` (transfers excluded). On CUDA the matcher is also timed
replayed as a CUDA graph (``CudaGraphSgm``). ``ratio_to_fastest``: ms / the fastest method's ms.
OpenCV is skipped where it is not installed.

Aggregation (``SgmCfg.aggregation``): ``--aggregation`` sets the matcher's, reported under
``ours_sgm_<device>`` / ``ours_sgm_cuda_graph`` (and ``ratio``); ``both`` (the default) sets "auto"
there and times the matcher with the other one too, as ``ours_sgm_<device>_<torch|warp>_aggregation``
and ``ours_sgm_cuda_graph_<...>_aggregation``. ``aggregation_ms`` times the aggregation step alone on
the pair's cost volume (median ms per aggregation; ``aggregation_identical``: whether they agree to
the bit). Warp compiles its kernels on the first call (cached on disk): the warm-up run absorbs it.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import time
from pathlib import Path

import numpy as np
import torch

from ambulo.perception.stereo.sgbm_opencv import SgbmCfg, sgbm_disparity
from ambulo.perception.stereo.sgm import (
    CudaGraphSgm,
    SgmCfg,
    aggregate_with,
    census,
    census_cost,
    grey_levels,
    resolve_aggregation,
    sgm_disparity,
)


def warp_version() -> str | None:
    """warp-lang's version, None where it is not installed (the matcher then aggregates in torch)."""
    try:
        import warp

        return warp.config.version
    except ImportError:
        return None


def load_pair(path: Path | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(left, right, truth): (H, W, 3) uint8 RGB twice and the (H, W) float32 true disparity, px
    (non-finite where unknown), from ``path`` (an .npz from ``--save-pair``) or scikit-image."""
    if path is not None:
        with np.load(path) as pair:
            return pair["left"], pair["right"], pair["truth"]
    from skimage.data import stereo_motorcycle  # not needed with --pair

    return stereo_motorcycle()


def scores(disparity: np.ndarray, truth: np.ndarray) -> dict:
    """Density, bad 2.0 and median |error| of a disparity (nan: none) against the truth."""
    known = np.isfinite(truth)
    both = known & np.isfinite(disparity)
    error = np.abs(disparity[both] - truth[both])
    return {"density": round(float(both.sum() / known.sum()), 4), "bad2": round(float((error > 2.0).mean()), 4),
            "median_error_px": round(float(np.median(error)), 3)}


def median_ms(run, repeats: int, sync=lambda: None) -> tuple[float, object]:
    """Median wall time of ``run()`` over ``repeats`` calls after a warm-up, ms, and its last output."""
    out = run()
    sync()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        out = run()
        sync()
        times.append(1e3 * (time.perf_counter() - start))
    return statistics.median(times), out


def opencv_bm(left: np.ndarray, right: np.ndarray, num_disparities: int) -> np.ndarray:
    """OpenCV's StereoBM (SAD block matching with a prefilter, texture and uniqueness checks and
    speckle filtering; 15 px blocks) as float32 disparity, nan where it found none."""
    import cv2

    grey = [cv2.cvtColor(img, cv2.COLOR_RGB2GRAY) for img in (left, right)]
    matcher = cv2.StereoBM_create(numDisparities=num_disparities, blockSize=15)
    matcher.setUniquenessRatio(10)
    matcher.setSpeckleWindowSize(100)
    matcher.setSpeckleRange(2)
    disparity = matcher.compute(*grey).astype(np.float32) / 16.0  # fixed point, 4 fractional bits
    disparity[disparity <= 0] = np.nan
    return disparity


def time_aggregations(left: torch.Tensor, right: torch.Tensor, cfg: SgmCfg, aggregations: list[str], repeats: int,
                      sync) -> tuple[dict, bool | None]:
    """Median ms of the aggregation step alone for each of ``aggregations`` on the pair's (D, H, W)
    cost volume, and whether they all gave the same volume (None for one)."""
    signatures = [census(grey_levels(img), cfg.census_rows, cfg.census_cols) for img in (left, right)]
    cost = census_cost(*signatures, cfg.num_disparities)
    times, volumes = {}, []
    for aggregation in aggregations:
        agg_cfg = dataclasses.replace(cfg, aggregation=aggregation)
        ms, volume = median_ms(lambda c=agg_cfg: aggregate_with(cost, c), repeats, sync)
        times[aggregation] = round(ms, 2)
        volumes.append(volume)
    identical = all(torch.equal(volumes[0], v) for v in volumes[1:]) if len(volumes) > 1 else None
    return times, identical


def time_matcher(l_dev: torch.Tensor, r_dev: torch.Tensor, truth: np.ndarray, cfg: SgmCfg, repeats: int, sync,
                 suffix: str = "") -> tuple[dict, str | None]:
    """``methods`` entries of the matcher with ``cfg``, eager and, on CUDA, replayed as a CUDA graph
    (keys ``ours_sgm_<device><suffix>``, ``ours_sgm_cuda_graph<suffix>``), and the graph's error if
    its capture failed."""
    device = l_dev.device
    aggregation = resolve_aggregation(cfg.aggregation, device)
    methods = {}
    ms, disparity = median_ms(lambda: sgm_disparity(l_dev, r_dev, cfg), repeats, sync)
    methods[f"ours_sgm_{device.type}{suffix}"] = {"ms": round(ms, 2), **scores(disparity.cpu().numpy(), truth),
                                                  "aggregation": aggregation}
    graph_error = None
    if device.type == "cuda":
        try:
            graphed = CudaGraphSgm(l_dev.shape, cfg, device)
            ms, disparity = median_ms(lambda: graphed(l_dev, r_dev), repeats, sync)
            methods[f"ours_sgm_cuda_graph{suffix}"] = {"ms": round(ms, 2), **scores(disparity.cpu().numpy(), truth),
                                                       "aggregation": aggregation}
        except RuntimeError as error:  # a capture that fails still leaves the eager figures
            graph_error = str(error)[:500]
    return methods, graph_error


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--num-disparities", type=int, default=64)
    parser.add_argument("--paths", type=int, default=8, choices=(4, 8))
    parser.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: torch's)")
    parser.add_argument("--aggregation", default="both", choices=("both", "auto", "torch", "warp"),
                        help="the matcher's SgmCfg.aggregation; both: auto, and time the other one too")
    parser.add_argument("--pair", type=Path, default=None, help=".npz from --save-pair instead of scikit-image")
    parser.add_argument("--save-pair", type=Path, default=None, help="write the pair as .npz and exit")
    args = parser.parse_args(argv)
    left, right, truth = load_pair(args.pair)
    if args.save_pair is not None:
        args.save_pair.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(args.save_pair, left=left, right=right, truth=truth)
        return {}
    if args.threads is not None:
        torch.set_num_threads(args.threads)
    device = torch.device(args.device)
    sync = torch.cuda.synchronize if device.type == "cuda" else lambda: None
    methods = {}
    try:
        import cv2

        cv_threads = cv2.getNumThreads()
        ms, disparity = median_ms(lambda: sgbm_disparity(left, right, SgbmCfg(num_disparities=args.num_disparities)),
                                  args.repeats)
        methods["opencv_sgbm_cpu"] = {"ms": round(ms, 2), **scores(disparity, truth)}
        ms, disparity = median_ms(lambda: opencv_bm(left, right, args.num_disparities), args.repeats)
        methods["opencv_bm_cpu"] = {"ms": round(ms, 2), **scores(disparity, truth)}
    except ImportError:
        cv_threads = None
    main_setting = "auto" if args.aggregation == "both" else args.aggregation
    cfg = SgmCfg(num_disparities=args.num_disparities, paths=args.paths, aggregation=main_setting)
    l_dev, r_dev = torch.from_numpy(left).to(device), torch.from_numpy(right).to(device)
    aggregation = resolve_aggregation(main_setting, device)
    ours_methods, graph_error = time_matcher(l_dev, r_dev, truth, cfg, args.repeats, sync)
    methods.update(ours_methods)
    ours = list(ours_methods)[-1]  # the graph on CUDA when it was captured
    compared = [aggregation]
    other = {"warp": "torch", "torch": "warp"}[aggregation]
    other_error = None
    if args.aggregation == "both" and resolve_aggregation("auto", device) == "warp":  # Warp imports
        compared.append(other)
        other_cfg = dataclasses.replace(cfg, aggregation=other)
        other_methods, other_error = time_matcher(l_dev, r_dev, truth, other_cfg, args.repeats, sync,
                                                  suffix=f"_{other}_aggregation")
        methods.update(other_methods)
    aggregation_ms, identical = time_aggregations(l_dev, r_dev, cfg, compared, args.repeats, sync)
    fastest = min(m["ms"] for m in methods.values())
    for m in methods.values():
        m["ratio_to_fastest"] = round(m["ms"] / fastest, 3)
    result = {
        "benchmark": "stereo", "pair": f"middlebury2014-motorcycle (scikit-image, {left.shape[0]}x{left.shape[1]})",
        "num_disparities": args.num_disparities, "paths": args.paths,
        "device": torch.cuda.get_device_name(device) if device.type == "cuda" else "cpu",
        "torch_threads": torch.get_num_threads(), "opencv_threads": cv_threads, "repeats": args.repeats,
        "methods": methods, "ratio": methods[ours]["ratio_to_fastest"], "cuda_graph_error": graph_error,
        "aggregation": aggregation, "aggregation_ms": aggregation_ms, "aggregation_identical": identical,
        "other_aggregation_cuda_graph_error": other_error,
        "versions": {"torch": torch.__version__,
                     "opencv": __import__("cv2").__version__ if cv_threads is not None else None,
                     "warp": warp_version()},
    }
    print("RESULT " + json.dumps(result))
    return result


if __name__ == "__main__":
    main()
