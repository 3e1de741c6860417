"""The issue's domain-gap test: train on the example dataset, score on (a) its held-out seeds, (b)
randomization never seen in training, (c) another renderer; report the drop.

    python benchmarks/detect_domain_gap.py --frames 1000 --width 160 --height 120 --epochs 15 --out runs/gap
    python benchmarks/detect_domain_gap.py --checkpoint runs/det/checkpoint.pt --train-data data/ --out runs/gap
    python benchmarks/detect_domain_gap.py --checkpoint CK --width 320 --height 240 --eval-frames 200 --factors --no-pbr
    python benchmarks/detect_domain_gap.py --frames 10000 --width 320 --height 240 --generate-only --out runs/gap
    ambulo generate benchmarks/detect_domain_gap.py --frames 500 --out unseen/     # split (b) alone

This file is also an ``ambulo generate`` CONFIG: ``config()`` is split (b), the example scene
(``replicator.example_config``: same objects, same categories) with every randomization the
training data has moved outside its training range:

- textures: a palette drawn from another seed, every object textured (training: palette seed 0,
  30 % untextured);
- lighting: brighter (intensity 0.9-1.3, training 0.35-0.9), more ambient (0.3-0.45, training
  0.15-0.3) and lower (elevation 10-30 deg, training 30-75 deg);
- clutter: another pool of distractor shapes and colours, 6-10 of them (training 2-6) and larger; since
  session 9 a pool shape within 25 % of a class's geometry (the margin the hard negatives keep) is redrawn
  (``ClassFreeDistractors``): 3 of the 12 were ball-sized spheres, balls by geometry that no detector can
  reject, so the split scored them as a domain gap (earlier results files keep the old split's figures);
- camera height: the head camera 0.25-0.45 m above its mount (training: 1 cm standard deviation).

``--factors`` also scores split (b) with one factor moved at a time (``config(factors=...)``): which
one costs the most. ``--train-config generic`` trains on ``training_config()``: the example config
with generic variety added (a larger distractor pool, recoloured and textured every frame; more
object textures), all within the example config's own ranges, so split (b) stays unseen.

Split (c) is the example config drawn by MuJoCo 4's Filament renderer (``--renderer pbr``: PBR
materials and image-based lighting) instead of the raster renderer it was trained on; leave it out
with ``--no-pbr`` where Filament (Vulkan) is missing.

``detections_unseen.png`` in --out: the detector's boxes and masks (score >= 0.3) on the first
frames of split (b), frames no training ever saw.

RESULT: mAP/mAP50 (boxes and masks) and AP per class on each split, the drop of each split in
mAP50 points against (a), and ``ratio``: (b)'s box mAP50 over (a)'s, the in-distribution ceiling
measured in the same run (the issue's acceptance: (b) loses <= 10 points of mAP50).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import time
from pathlib import Path

import numpy as np

from ambulo import replicator as rep
from ambulo.core.randomize import uniform, uniform_int
from ambulo.replicator.hard_negatives import ClassFreeDistractors, HardNegatives

MOVED = {
    "object_materials": lambda r: dataclasses.replace(r, palette_seed=1001, untextured_probability=0.0),
    "lights": lambda r: dataclasses.replace(r, intensity=uniform(0.9, 1.3), ambient=uniform(0.3, 0.45),
                                            elevation_deg=uniform(10.0, 30.0)),
    # ClassFreeDistractors: a shape within 25 % of a class's geometry is a class, not clutter: redrawn
    "distractors": lambda r: ClassFreeDistractors(**{**{f.name: getattr(r, f.name) for f in dataclasses.fields(r)},
                                                     "pool_seed": 1002, "pool_size": 12, "count": uniform_int(6, 10),
                                                     "size_m": (0.1, 0.35)}),
    "camera_jitter": lambda r: dataclasses.replace(r, position_m=uniform((-0.01, -0.01, 0.25),
                                                                         (0.01, 0.01, 0.45))),
}
"""Split (b)'s change of each randomizer of the example config, by the randomizer's name."""
FACTORS = {"textures": "object_materials", "lighting": "lights", "clutter": "distractors",
           "camera_height": "camera_jitter"}
"""The four factors of split (b) (module docstring), each the randomizer it moves."""


def config(width: int = 320, height: int = 240, factors: tuple[str, ...] = tuple(FACTORS)) -> rep.DatasetConfig:
    """Split (b): the example dataset with its randomization moved outside the training ranges; with
    ``factors`` (names of ``FACTORS``), only those moved (the split's cost factor by factor)."""
    base = rep.example_config(width, height)
    moved = {FACTORS[f]: MOVED[FACTORS[f]] for f in factors}
    names = {r.name for r in base.randomizers}
    if not set(MOVED) <= names:  # the example config changed: this split must follow it
        raise RuntimeError(f"example_config has no randomizers {sorted(set(MOVED) - names)}")
    randomizers = [moved[r.name](r) if r.name in moved else r for r in base.randomizers]
    suffix = "" if set(factors) == set(FACTORS) else "_" + "_".join(factors)
    return dataclasses.replace(base, name="ambulo_warehouse_unseen" + suffix, randomizers=randomizers)


def training_config(width: int = 320, height: int = 240) -> rep.DatasetConfig:
    """The example dataset with generic, Replicator-style variety added for training (``--train-config
    generic``): more distinct things that are not objects, and more textures, each within the example
    config's own ranges, none of them split (b)'s (its palette, distractor pool, sizes and counts,
    lights and camera heights stay outside: the split remains a test of the unknown).

    - distractors: a pool of 32 primitives instead of 8 (same sizes 0.05-0.25 m, same 2-6 a frame), each
      recoloured every frame (HSV) and textured from their own palette (seed 7) 70 % of the time: the
      detector cannot learn the clutter by heart, it must learn what the objects are;
    - object textures: a palette of 24 procedural textures (seed 0, 30 % untextured as before) instead of 8.
    """
    base = rep.example_config(width, height)
    varied = {
        "distractors": lambda r: dataclasses.replace(r, pool_size=32),
        "object_materials": lambda r: dataclasses.replace(r, palette_size=24),
    }
    randomizers = [varied[r.name](r) if r.name in varied else r for r in base.randomizers]
    randomizers += [rep.ColorRandomizer(name="distractor_colors", prims="/World/distractors/*"),
                    rep.MaterialRandomizer(name="distractor_materials", prims="/World/distractors/*", palette_seed=7)]
    return dataclasses.replace(base, name="ambulo_warehouse_generic", randomizers=randomizers)


def split_b_pools() -> list[list[tuple[str, tuple]]]:
    """The distractor pool split (b) draws (``MOVED["distractors"]`` on the example config's
    ``Distractors``): the shapes training must never see, (kind, MuJoCo size) each."""
    base = next(r for r in rep.example_config().randomizers if r.name == "distractors")
    return [[(kind, size) for kind, size, _ in MOVED["distractors"](base).pool()]]


def hard_negative_config(width: int = 320, height: int = 240) -> rep.DatasetConfig:
    """The example dataset plus hard negatives (``--train-config hardneg``): 2-5 a frame of a pool of 32
    boxes, spheres, cylinders and ellipsoids (the classes' families) whose sizes are more than 25 %
    from every class's in some dimension (``replicator.hard_negatives``), coloured and textured as the
    objects are (same hue range, same palette seed) so that only geometry tells them apart.

    Split (b) stays unseen: the pool's seed (2027) is none of split (b)'s, and any drawn shape within
    25 % of one of split (b)'s 12 distractor shapes (``split_b_pools``) is redrawn; split (b)'s
    palette, lights and camera heights are untouched."""
    base = rep.example_config(width, height)
    region = next(r for r in base.randomizers if r.name == "distractors").region
    prims = "/World/hard_negatives/*"
    negatives = [HardNegatives(name="hard_negatives", prims=prims, region=region, surface="/World/floor/*",
                               count=uniform_int(2, 5), excluded_pools=split_b_pools()),
                 rep.ColorRandomizer(name="hard_negative_colors", prims=prims),
                 rep.MaterialRandomizer(name="hard_negative_materials", prims=prims)]
    at = [r.name for r in base.randomizers].index("distractors") + 1  # placed after the clutter, before colours
    randomizers = base.randomizers[:at] + negatives[:1] + base.randomizers[at:] + negatives[1:]
    return dataclasses.replace(base, name="ambulo_warehouse_hardneg", randomizers=randomizers)


TRAIN_CONFIGS = {"example": rep.example_config, "generic": training_config, "hardneg": hard_negative_config}
"""Training data of ``--train-config``: the example dataset as it is, with ``training_config``'s variety, or
with ``hard_negative_config``'s hard negatives."""


PALETTE = np.array([[230, 25, 75], [60, 180, 75], [255, 225, 25], [0, 130, 200], [245, 130, 48], [145, 30, 180]],
                   np.uint8)


def draw_detections(checkpoint: Path, frames: list[Path], out: Path, score_threshold: float = 0.3) -> Path:
    """One PNG of ``frames`` side by side with the detector's masks (tinted) and boxes (labelled)."""
    import imageio.v3 as iio
    from PIL import Image, ImageDraw

    from ambulo.detection import Detector
    from ambulo.detection.dataset import read_height_m

    detector = Detector(checkpoint, score_threshold)
    tiles = []
    for path in frames:
        rgb = iio.imread(path)[..., :3]
        # an rgbd detector: the frame's depth PNG (mm, replicator.writers' layout)
        depth_m = iio.imread(path.parent.parent / "depth" / path.name) / 1000.0 if detector.needs_depth else None
        # an rgbdh detector: each pixel's height above the floor, from that depth and the frame record's camera
        height_m = read_height_m(path.parent.parent, {"file_name": path.name}, depth_m * 1000.0) \
            if detector.needs_height else None
        found = detector(rgb, depth_m, height_m)
        shown = rgb.astype(np.float32)
        classes = [detector.categories.index(label) for label in found.labels]
        for k in np.argsort(found.scores) if found.masks is not None else []:
            colour = PALETTE[classes[k] % len(PALETTE)]
            shown[found.masks[k]] = 0.5 * shown[found.masks[k]] + 0.5 * colour
        image = Image.fromarray(shown.astype(np.uint8))
        pen = ImageDraw.Draw(image)
        for box, label, score, cls in zip(found.boxes_px.tolist(), found.labels, found.scores.tolist(), classes):
            colour = tuple(int(v) for v in PALETTE[cls % len(PALETTE)])
            pen.rectangle(box, outline=colour)
            pen.text((box[0], max(0, box[1] - 10)), f"{label} {score:.2f}", fill=colour)
        tiles.append(np.asarray(image))
    iio.imwrite(out, np.concatenate(tiles, axis=1))
    return out


def score(checkpoint: Path, splits: dict[str, tuple[Path, float | None, bool]], device: str,
          processes: int) -> dict[str, dict]:
    """``evaluate_checkpoint`` of each split {name: (folder, held-out fraction or None, with masks)}, in
    ``processes`` processes at once (spawned: each its own CUDA context) or one after the other."""
    from ambulo.detection import evaluate_checkpoint

    def job(folder, fraction, masks):
        return dict(checkpoint=checkpoint, dataset_dir=folder, held_out_fraction=fraction, device=device, masks=masks)

    if processes <= 1:
        return {name: evaluate_checkpoint(**job(*split)) for name, split in splits.items()}
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(processes, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = {name: pool.submit(evaluate_checkpoint, **job(*split)) for name, split in splits.items()}
        return {name: future.result() for name, future in futures.items()}


def make(cfg: rep.DatasetConfig, out: Path, frames: int, seed: int, workers: int) -> Path:
    start = time.perf_counter()
    rep.generate(cfg, out, num_frames=frames, seed=seed, workers=workers, show_progress=False)
    print(f"{out}: {frames} frames in {time.perf_counter() - start:.0f} s", flush=True)
    return out


def main() -> None:
    from ambulo.detection import AugmentCfg, TrainCfg, generic, geometry_only, train, viewpoint

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="runs/domain_gap", help="datasets, run and result.json go here")
    parser.add_argument("--frames", type=int, default=1000, help="training dataset frames (10 %% held out)")
    parser.add_argument("--eval-frames", type=int, default=0, help="frames of splits (b), (c) (default: the held-out count)")
    parser.add_argument("--width", type=int, default=160)
    parser.add_argument("--height", type=int, default=120)
    parser.add_argument("--epochs", type=int, default=15)
    parser.add_argument("--batch-size", type=int, default=16)
    parser.add_argument("--lr", type=float, default=3e-3)
    parser.add_argument("--model", default="centernet-small")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--workers", type=int, default=min(4, os.cpu_count() or 1), help="generation and loading")
    parser.add_argument("--checkpoint", default=None, help="score this checkpoint instead of training one")
    parser.add_argument("--train-data", default=None,
                        help="the dataset --checkpoint was trained on (without it, split (a) is --eval-frames "
                             "frames of the example config drawn with a seed training never used)")
    parser.add_argument("--train-config", choices=tuple(TRAIN_CONFIGS), default="example",
                        help="training data: the example config, or it with generic variety (training_config)")
    parser.add_argument("--factors", action="store_true",
                        help="also score split (b)'s factors one at a time (lighting, textures, clutter, camera "
                             "height only; same seed and size): which one costs the most")
    parser.add_argument("--no-pbr", action="store_true", help="leave out split (c), the Filament renderer")
    parser.add_argument("--augment", choices=("full", "generic", "geometry", "viewpoint"), default="full",
                        help="training augmentations: full (ambulo.detection.augment's defaults), generic (those "
                             "plus clutter-like occluders and uneven light: augment.generic), viewpoint (the "
                             "defaults plus the camera pitched and rolled: augment.viewpoint) or geometry only")
    parser.add_argument("--inputs", choices=("rgb", "rgbd", "rgbdh"), default="rgb",
                        help="the model's input: colour, or colour and depth, or those and the height above the "
                             "floor (TrainCfg.inputs)")
    parser.add_argument("--seed", type=int, default=0, help="training seed (initialisation, shuffling, augmentation)")
    parser.add_argument("--max-minutes", type=float, default=0.0, help="training budget (TrainCfg.max_minutes)")
    parser.add_argument("--score-processes", type=int, default=1,
                        help="score the splits in this many processes at once (a GPU machine's spare cores)")
    parser.add_argument("--generate-only", action="store_true",
                        help="make the datasets in --out and stop (a later run with the same --out and sizes reuses "
                             "them: `ambulo generate` finishes a dataset, it does not redo it)")
    args = parser.parse_args()
    out = Path(args.out)
    held_out_fraction = 0.1
    eval_frames = args.eval_frames or max(1, round(args.frames * held_out_fraction))
    fresh_held_out = args.checkpoint is not None and args.train_data is None
    if fresh_held_out:  # seed 3: no training run here drew it
        train_data = make(rep.example_config(args.width, args.height), out / "held_out", eval_frames, 3, args.workers)
    else:
        train_data = Path(args.train_data) if args.train_data else make(
            TRAIN_CONFIGS[args.train_config](args.width, args.height), out / "train", args.frames, 0, args.workers)
    splits = {"unseen_randomization": make(config(args.width, args.height), out / "unseen", eval_frames, 1,
                                           args.workers)}
    if args.train_config != "example":  # the example dataset's own frames (seed 3: unused), to compare with its runs
        splits["example_config"] = make(rep.example_config(args.width, args.height), out / "example", eval_frames, 3,
                                         args.workers)
    for factor in FACTORS if args.factors else ():
        splits[f"unseen_{factor}_only"] = make(config(args.width, args.height, (factor,)),
                                               out / f"unseen_{factor}", eval_frames, 1, args.workers)
    if not args.no_pbr:
        pbr = rep.example_config(args.width, args.height)
        pbr = dataclasses.replace(pbr, camera=dataclasses.replace(pbr.camera, renderer="pbr"))
        splits["pbr_renderer"] = make(pbr, out / "pbr", eval_frames, 2, args.workers)
    if args.generate_only:
        return
    summary: dict = {"frames": args.frames, "size": [args.width, args.height], "device": args.device,
                     "augment": args.augment, "train_config": args.train_config, "inputs": args.inputs,
                     "seed": args.seed}
    checkpoint = args.checkpoint
    if checkpoint is None:
        cfg = TrainCfg(model=args.model, epochs=args.epochs, batch_size=args.batch_size, learning_rate=args.lr,
                       device=args.device, num_workers=args.workers, held_out_fraction=held_out_fraction,
                       # a time budget evaluates on the clock (its epochs count is only a ceiling), else 5 times
                       eval_every_epochs=0 if args.max_minutes > 0 else max(1, args.epochs // 5),
                       eval_every_minutes=args.max_minutes / 6 if args.max_minutes > 0 else 0.0,
                       max_minutes=args.max_minutes, inputs=args.inputs, seed=args.seed,
                       augment={"full": AugmentCfg, "generic": generic, "geometry": geometry_only,
                                "viewpoint": viewpoint}[args.augment]())
        start = time.perf_counter()
        result = train(train_data, out / "run", cfg)
        summary["train"] = {"epochs": args.epochs, "steps": result.step, "seconds": round(time.perf_counter() - start),
                            "stopped": result.stopped, "model": args.model, "batch_size": args.batch_size,
                            "curve": [{k: e[k] for k in ("epoch", "step", "elapsed_s", "mAP", "mAP50")}
                                      for e in result.evaluations]}
        checkpoint = out / "run" / "checkpoint.pt"
    # the factor splits score boxes only: they say which factor costs the most, the whole split (b) says how much
    jobs = {"held_out_seeds": (train_data, None if fresh_held_out else held_out_fraction, True)}
    jobs.update({name: (folder, None, not name.endswith("_only")) for name, folder in splits.items()})
    scores = score(Path(checkpoint), jobs, args.device, args.score_processes)
    base = scores["held_out_seeds"]
    summary["splits"] = scores
    summary["drop_mAP50_points"] = {name: round(100 * (base["mAP50"] - s["mAP50"]), 1) for name, s in scores.items()
                                    if name != "held_out_seeds"}
    summary["drop_mask_mAP50_points"] = {name: round(100 * (base["mask"]["mAP50"] - s["mask"]["mAP50"]), 1)
                                         for name, s in scores.items() if name != "held_out_seeds" and "mask" in s}
    summary["ratio"] = round(scores["unseen_randomization"]["mAP50"] / base["mAP50"], 3) if base["mAP50"] else None
    for name, s in scores.items():
        masks = f", masks mAP {s['mask']['mAP']:.3f} mAP50 {s['mask']['mAP50']:.3f}" if "mask" in s else ""
        masks += f", semantic mIoU {s['semantic']['mIoU']:.3f}" if "semantic" in s else ""
        print(f"{name:>26}: {s['frames']} frames, boxes mAP {s['mAP']:.3f} mAP50 {s['mAP50']:.3f}{masks}")
    unseen_frames = sorted((splits["unseen_randomization"] / "rgb").glob("*.png"))[:4]
    summary["image"] = str(draw_detections(Path(checkpoint), unseen_frames, out / "detections_unseen.png"))
    (out / "result.json").write_text(json.dumps(summary, indent=1))
    print("RESULT " + json.dumps(summary))


if __name__ == "__main__":
    main()
