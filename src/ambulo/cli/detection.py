"""``ambulo train-detector`` and ``ambulo export-detector``: a detector trained from scratch on an
``ambulo generate`` dataset, and its ONNX export checked against torch.

    ambulo generate --frames 2000 --out data/ --seed 0
    ambulo train-detector data/ --epochs 30 --device cuda --out runs/det     # --resume continues it
    ambulo train-detector data/ --epochs 1000 --max-minutes 12 --device cuda --workers 16 --out runs/det
    ambulo export-detector runs/det/checkpoint.pt --out runs/det/model.onnx
    ambulo evaluate-detector runs/det/checkpoint.pt other_data/               # mAP on another dataset
    tensorboard --logdir runs/det
"""

from __future__ import annotations

import argparse
from pathlib import Path

from .errors import CliError

MODEL_NAMES = ("centernet-small", "centernet-medium")
"""``ambulo.detection.MODELS``' names, here so that building the parser imports no torch."""


def train_detector(args: argparse.Namespace) -> int:
    import torch

    from ambulo.detection import (
        CHECKPOINT,
        AugmentCfg,
        DatasetError,
        TrainCfg,
        generic,
        geometry_only,
        no_augment,
        viewpoint,
    )
    from ambulo.detection import train as train_run

    AUGMENTS = {"full": AugmentCfg, "generic": generic, "geometry": geometry_only, "none": no_augment,
                "viewpoint": viewpoint}

    for flag in ("epochs", "batch_size"):
        if getattr(args, flag) < 1:
            raise CliError(f"--{flag.replace('_', '-')} {getattr(args, flag)} is not positive", "give 1 or more")
    if args.device.startswith("cuda") and not torch.cuda.is_available():
        raise CliError(f"--device {args.device} but torch sees no CUDA GPU", "use --device cpu")
    if not args.resume and (Path(args.out) / CHECKPOINT).exists():
        raise CliError(f"{args.out} already holds a training run", "give --resume to continue it, or another --out")
    if args.mask_prototypes < 0:
        raise CliError(f"--mask-prototypes {args.mask_prototypes} is negative", "give 0 (boxes only) or more")
    for flag in ("max_minutes", "pause_after_minutes", "eval_every_minutes"):
        if getattr(args, flag) < 0:
            raise CliError(f"--{flag.replace('_', '-')} {getattr(args, flag)} is negative", "give 0 (none) or more")
    cfg = TrainCfg(model=args.model, epochs=args.epochs, batch_size=args.batch_size, device=args.device,
                   eval_every_epochs=args.eval_every, num_workers=args.workers, learning_rate=args.lr,
                   seed=args.seed, mask_prototypes=args.mask_prototypes, data=args.data,
                   max_minutes=args.max_minutes, pause_after_minutes=args.pause_after_minutes,
                   eval_every_minutes=args.eval_every_minutes, augment=AUGMENTS[args.augment](),
                   inputs=args.inputs)
    try:
        result = train_run(args.dataset, args.out, cfg, resume=args.resume, show_progress=not args.quiet)
    except DatasetError as err:
        raise CliError(err.problem, err.fix) from None
    last = result.evaluations[-1] if result.evaluations else None
    if last is not None:
        classes = ", ".join(f"{name} {ap:.3f}" for name, ap in last["per_class"].items())
        print(f"held-out frames: mAP {last['mAP']:.3f}, mAP50 {last['mAP50']:.3f} ({classes})")
        if "mask" in last:
            masks = last["mask"]
            classes = ", ".join(f"{name} {ap:.3f}" for name, ap in masks["per_class"].items())
            print(f"held-out masks:  mAP {masks['mAP']:.3f}, mAP50 {masks['mAP50']:.3f} ({classes})")
        _print_semantic("held-out semantic", last)
    if result.stopped == "pause":
        print(f"paused after {result.elapsed_s / 60:.1f} min of training; continue with the same command and --resume")
    elif result.stopped == "budget":
        print(f"stopped at the {args.max_minutes:g}-minute budget in epoch {result.epoch + 1}")
    print(f"trained {result.step} steps; checkpoint {Path(args.out) / CHECKPOINT}; TensorBoard: "
          f"tensorboard --logdir {args.out}")
    return 0


def export_detector(args: argparse.Namespace) -> int:
    from ambulo.detection import check_onnx, export_onnx

    if not Path(args.checkpoint).is_file():
        raise CliError(f"no checkpoint {args.checkpoint}", "give the checkpoint.pt of `ambulo train-detector`")
    out = export_onnx(args.checkpoint, args.out)
    diff = check_onnx(args.checkpoint, out)
    if diff["scores"] > 1e-4 or diff.get("masks", 0.0) > 1e-3 or diff["unmatched"] > 0.1 * diff["compared"]:
        raise CliError(f"ONNX Runtime disagrees with torch (scores by {diff['scores']:.3g}, {diff['unmatched']} of "
                       f"{diff['compared']} boxes unmatched)", "report this with the checkpoint; the export is kept")
    masks = f", masks within {diff['masks']:.2g}" if "masks" in diff else ""
    print(f"wrote {out} (+ {out}.json); ONNX Runtime matches torch: boxes within {diff['boxes_px']:.2g} px, "
          f"scores within {diff['scores']:.2g}{masks} ({diff['compared']} boxes compared, {diff['unmatched']} moved by "
          "a cell where neighbouring scores tie)")
    return 0


def _print_metrics(what: str, metrics: dict) -> None:
    classes = ", ".join(f"{name} {ap:.3f}" for name, ap in metrics["per_class"].items())
    print(f"{what}: mAP {metrics['mAP']:.3f}, mAP50 {metrics['mAP50']:.3f} ({classes})")


def evaluate_detector(args: argparse.Namespace) -> int:
    from ambulo.detection import DatasetError, evaluate_checkpoint

    if not Path(args.checkpoint).is_file():
        raise CliError(f"no checkpoint {args.checkpoint}", "give the checkpoint.pt of `ambulo train-detector`")
    if args.held_out is not None and not 0 < args.held_out < 1:
        raise CliError(f"--held-out {args.held_out} is not a fraction in (0, 1)", "give e.g. 0.1, or leave it out")
    try:
        metrics = evaluate_checkpoint(args.checkpoint, args.dataset, args.held_out, device=args.device)
    except DatasetError as err:
        raise CliError(err.problem, err.fix) from None
    _print_metrics(f"{metrics['frames']} frames, boxes", metrics)
    if "mask" in metrics:
        _print_metrics(f"{metrics['frames']} frames, masks", metrics["mask"])
    _print_semantic(f"{metrics['frames']} frames, semantic", metrics)
    return 0


def _print_semantic(label: str, metrics: dict) -> None:
    """The semantic block of an evaluation (mask models only), one line."""
    sem = metrics.get("semantic")
    if sem is None:
        return
    classes = ", ".join(f"{name} {iou:.3f}" for name, iou in sem["per_class"].items())
    print(f"{label}: mIoU {sem['mIoU']:.3f}, pixel accuracy {sem['pixel_acc']:.3f} ({classes})")


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    """Add ``train-detector``, ``export-detector`` and ``evaluate-detector`` to the ``ambulo`` parser."""
    p = subparsers.add_parser("train-detector", help="train an object detector on an `ambulo generate` dataset",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dataset", help="folder made by `ambulo generate` (annotations.json + rgb/)")
    p.add_argument("--model", choices=MODEL_NAMES, default="centernet-small", help="detector (default centernet-small)")
    p.add_argument("--device", default="cpu", help="torch device: cpu or cuda (bfloat16 autocast on cuda)")
    p.add_argument("--epochs", type=int, default=30, help="passes over the training frames (default 30)")
    p.add_argument("--batch-size", type=int, default=16, help="frames per step (default 16)")
    p.add_argument("--lr", type=float, default=2e-3, help="AdamW peak learning rate (default 2e-3)")
    p.add_argument("--eval-every", type=int, default=5, help="COCO evaluation of held-out frames every N epochs")
    p.add_argument("--eval-every-minutes", type=float, default=0.0,
                   help="also evaluate after the first epoch this long after the last evaluation (default 0: off)")
    p.add_argument("--max-minutes", type=float, default=0.0,
                   help="training budget across resumes: stop, evaluate and checkpoint at it; the learning rate "
                        "anneals over it (default 0: the epochs decide)")
    p.add_argument("--pause-after-minutes", type=float, default=0.0,
                   help="stop this call after this long with a checkpoint, to --resume later (default 0: never)")
    p.add_argument("--data", choices=("resident", "stream"), default="resident",
                   help="resident: decode the training frames once into the device's memory (default); stream: "
                        "decode each batch in --workers processes (datasets larger than memory)")
    p.add_argument("--augment", choices=("full", "generic", "geometry", "none", "viewpoint"), default="full",
                   help="full: geometric, occlusion and photometric augmentations on the device (default); "
                        "generic: those plus clutter-like occluders and uneven light (augment.generic); "
                        "geometry: flips and scale jitter only; none; viewpoint: full plus the camera pitched and "
                        "rolled (augment.viewpoint)")
    p.add_argument("--inputs", choices=("rgb", "rgbd", "rgbdh"), default="rgb",
                   help="rgb: colour frames (default); rgbd: colour and the dataset's depth PNGs as a 4th channel "
                        "(the model can measure metric size; its Detector then needs depth with every frame); "
                        "rgbdh: those and each pixel's height above the floor, from the depth and the frame "
                        "records' camera poses (the same from any camera height; the Detector needs it too)")
    p.add_argument("--workers", type=int, default=2, help="image-decoding processes (default 2)")
    p.add_argument("--seed", type=int, default=0, help="initialisation and shuffling seed (default 0)")
    p.add_argument("--mask-prototypes", type=int, default=8,
                   help="instance masks from the dataset's segmentation with this many prototypes (0: boxes only)")
    p.add_argument("--out", default="runs/detector", help="run folder: checkpoint, metrics, TensorBoard")
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its checkpoint")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=train_detector)
    e = subparsers.add_parser("export-detector", help="export a trained detector to ONNX (checked with ONNX Runtime)",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    e.add_argument("checkpoint", help="checkpoint.pt of `ambulo train-detector`")
    e.add_argument("--out", required=True, help="the .onnx file to write (its categories go to <out>.json)")
    e.set_defaults(func=export_detector)
    v = subparsers.add_parser("evaluate-detector", help="COCO mAP of a trained detector on a dataset (boxes, masks)",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    v.add_argument("checkpoint", help="checkpoint.pt of `ambulo train-detector`")
    v.add_argument("dataset", help="folder made by `ambulo generate` with the detector's categories (by name)")
    v.add_argument("--held-out", type=float, default=None,
                   help="score only the last fraction of the frames (the split training held out); default all")
    v.add_argument("--device", default="cpu", help="torch device")
    v.set_defaults(func=evaluate_detector)
