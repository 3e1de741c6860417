"""``ambulo generate``: make a labelled, randomized dataset (COCO + PNGs) from a config or the example scene.

    ambulo generate --frames 100 --out data/ --seed 0              # the warehouse example
    ambulo generate my_config.py --frames 1000 --out data/ --workers 4
    ambulo generate --frames 100 --out data_pbr/ --renderer pbr      # Filament colours, same labels
    RAY_ADDRESS=auto ambulo generate my_config.py --frames 100000 --out /shared/data --workers 64

A CONFIG file is Python defining ``config()`` (or ``CONFIG``) that returns an
``ambulo.replicator.DatasetConfig``. Re-running the same command finishes an
interrupted dataset (Ctrl-C keeps what is done); the same seed gives byte-identical
files. --out must be a new or empty folder, or a dataset made with the same config,
seed and size; --overwrite starts a dataset afresh (only its own files are deleted).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import errno
import runpy
import signal
import sys
import threading
from pathlib import Path

from .errors import CliError
from .viewer_args import add_viewer_args, web_watch

_DISK_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EACCES, errno.EPERM, errno.EROFS)
"""Errors of the disk under --out, not of ambulo: one line, and the frames done are kept."""
_CONFIG_FIX = "give a Python file whose config() or CONFIG is an ambulo.replicator.DatasetConfig"


def load_config(path: str | None, width: int | None = None, height: int | None = None,
                renderer: str | None = None):
    """The ``DatasetConfig`` of Python file ``path`` (the example scene's for ``None``), with its
    camera resized to ``width`` x ``height`` and drawn by ``renderer`` where given. ``CliError`` on
    a bad file."""
    from ambulo import replicator as rep

    if path is None:
        config = rep.example_config()
    else:
        file = Path(path)
        if not file.is_file():
            raise CliError(f"config file {path!r} not found",
                           "check the path, or leave it out for the example scene")
        try:
            namespace = runpy.run_path(str(file))
        except SyntaxError as err:  # the user's file does not parse: where, not our traceback
            raise CliError(f"{err.filename}:{err.lineno}: {err.msg}", "fix the config file's Python syntax") from None
        if "config" in namespace and callable(namespace["config"]):
            config = namespace["config"]()
        elif "CONFIG" in namespace:
            config = namespace["CONFIG"]
        else:
            raise CliError(f"{path} defines neither config() nor CONFIG", _CONFIG_FIX)
        if not isinstance(config, rep.DatasetConfig):
            raise CliError(f"{path} gave a {type(config).__name__}, not a DatasetConfig", _CONFIG_FIX)
    if width or height or renderer:
        camera = dataclasses.replace(config.camera, width=width or config.camera.width,
                                     height=height or config.camera.height,
                                     renderer=renderer or config.camera.renderer)
        config = dataclasses.replace(config, camera=camera)
    return config


def generate(args: argparse.Namespace) -> int:
    from ambulo import replicator as rep
    from ambulo.replicator.manifest import DatasetFolderError

    for flag in ("frames", "workers", "width", "height"):
        value = getattr(args, flag)
        if value is not None and value < 1:
            raise CliError(f"--{flag} {value} is not positive", f"give --{flag} 1 or more")
    if args.seed < 0:
        raise CliError(f"--seed {args.seed} is negative", "give --seed 0 or more")
    if args.device is not None and args.workers not in (None, 1):
        raise CliError(f"--device {args.device} renders every frame of a batch in one launch on one GPU",
                       "drop --workers (or drop --device to render on the CPU's processes)")
    if args.num_gpus != 1 and (args.device is None or args.num_gpus < 1):
        raise CliError(f"--num-gpus {args.num_gpus} splits the batched GPU path", "give --device cuda and 1 or more GPUs")
    if args.num_worlds < 1:
        raise CliError(f"--num-worlds {args.num_worlds} is not positive", "give --num-worlds 1 or more")
    if args.draw_workers < 0 or (args.draw_workers and (args.device is None or args.num_gpus > 1)):
        raise CliError(f"--draw-workers {args.draw_workers} feeds the one-GPU batched path",
                       "give --device cuda (one GPU) with it, or drop it")
    share = None
    if args.cpu_jpeg_share is not None:
        from ambulo.replicator.cpu_jpeg import share_fraction

        if args.image_format != "jpg":
            raise CliError("--cpu-jpeg-share splits the JPEG encode", "give --image-format jpg with it, or drop it")
        try:
            share = share_fraction(args.cpu_jpeg_share)
        except (ValueError, ZeroDivisionError):
            raise CliError(f"--cpu-jpeg-share {args.cpu_jpeg_share} is not a share from 0 to 1",
                           "give e.g. 1/3, 0.25 or 0") from None
    if args.image_format == "jpg":
        from ambulo.replicator.encode import jpeg_available

        if args.device is None or args.num_gpus > 1:
            raise CliError("--image-format jpg encodes the RGB images on the GPU of the batched path",
                           "give --device cuda (one GPU) with it, or drop it (PNG)")
        if not jpeg_available(args.device):
            raise CliError(f"--image-format jpg needs torchvision's JPEG encoder on {args.device}",
                           "install the torchvision built for this torch, or drop --image-format (PNG)")
    watch = web_watch(args)
    if watch is not None and (args.image_format == "jpg" or args.workers not in (None, 1) or args.ray
                              or args.num_gpus > 1):
        raise CliError("--viewer web watches the frames rendered in this process; --workers, --ray and "
                       "--num-gpus render in other processes", "drop them (one process renders), or drop --viewer")
    config = load_config(args.config, args.width, args.height, args.renderer)
    if args.device is not None and config.camera.renderer != "raster":
        raise CliError(f"--device renders with MuJoCo Warp's ray caster, not renderer={config.camera.renderer!r}",
                       "drop --renderer (or --device, to render pbr/path on the CPU)")
    if args.device is not None and config.visible_fraction:
        raise CliError("--device cannot compute visible_fraction (one isolated render per object)",
                       "set visible_fraction=False in the config, or drop --device")
    try:
        with _terminate_as_interrupt() as received:
            path = rep.generate(config, args.out, num_frames=args.frames, seed=args.seed, workers=args.workers,
                                show_progress=not args.quiet, backend="ray" if args.ray else "auto",
                                overwrite=args.overwrite, device=args.device, num_worlds=args.num_worlds,
                                num_gpus=args.num_gpus, watch=watch, draw_workers=args.draw_workers,
                                image_format=args.image_format,
                                **({} if share is None else {"cpu_jpeg_share": share}))
    except DatasetFolderError as err:
        raise CliError(err.problem, err.fix) from None
    except OSError as err:
        if err.errno not in _DISK_ERRORS:
            raise
        raise CliError(f"can't write the dataset: {err.strerror} ({err.filename})",
                       "free space or fix permissions, then run the same command again to resume") from None
    except KeyboardInterrupt:
        signum = received[0] if received else signal.SIGINT
        print(f"ambulo generate: stopped by {signal.Signals(signum).name} with {_records(args.out)} of "
              f"{args.frames} frames written in {args.out}; run the same command again to resume",
              file=sys.stderr)
        return 128 + signum
    if not path.is_file():
        raise CliError(f"generate finished but {path} is missing", "check the disk and --out, then run again")
    print(f"wrote a dataset of {args.frames} frames in {args.out} (COCO annotations: {path})")
    return 0


@contextlib.contextmanager
def _terminate_as_interrupt():
    """SIGTERM (``kill``, a batch system) stops generation as Ctrl-C does: the frames being
    written are finished and the folder stays resumable. Yields the signals received; a
    second signal while stopping is ignored, so the stop itself can't be cut short."""
    received: list[int] = []
    if threading.current_thread() is not threading.main_thread():  # only it may set handlers
        yield received
        return

    def stop(signum, frame):
        received.append(signum)
        if len(received) == 1:
            raise KeyboardInterrupt

    previous = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield received
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def _records(out: Path) -> int:
    """The frames with a record in ``out`` (lines of the journals in ``frames/``)."""
    from ambulo.replicator.records import count_records

    with contextlib.suppress(OSError):
        return count_records(Path(out) / "frames")
    return 0


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    """Add ``generate`` to the ``ambulo`` parser."""
    p = subparsers.add_parser("generate", help="generate a labelled synthetic dataset (COCO)",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("config", nargs="?", default=None, help="Python file defining config(); default: example scene")
    p.add_argument("--frames", type=int, default=100, help="number of frames (default 100)")
    p.add_argument("--out", type=Path, required=True, help="output folder: new, empty, or a dataset to resume or extend (same config, seed and size)")
    p.add_argument("--seed", type=int, default=0, help="randomization seed (default 0)")
    p.add_argument("--workers", type=int, default=None,
                   help="processes rendering in parallel (default: one per CPU, fewer for short runs)")
    p.add_argument("--ray", action="store_true",
                   help="run the workers on Ray (also when RAY_ADDRESS is set): for several machines sharing --out")
    p.add_argument("--width", type=int, default=None, help="override the camera width (px)")
    p.add_argument("--height", type=int, default=None, help="override the camera height (px)")
    p.add_argument("--renderer", choices=("raster", "pbr", "path"), default=None,
                   help="what draws the colour images: raster (MuJoCo), pbr (Filament, physically based) or path "
                        "(path traced); labels are the same whichever (default: the config's camera, raster)")
    p.add_argument("--overwrite", action="store_true",
                   help="delete the ambulo dataset in --out (its own files only) and start afresh")
    p.add_argument("--device", default=None,
                   help="render --num-worlds frames per launch with MuJoCo Warp on this device (cuda, cuda:1; cpu: "
                        "Warp's CPU device): the CPU path's scenes and labels, ray-cast colours (default: the CPU)")
    p.add_argument("--num-worlds", type=int, default=64, help="frames per launch with --device (default 64)")
    p.add_argument("--num-gpus", type=int, default=1,
                   help="with --device cuda: one process per GPU (cuda:0 ...), each rendering whole launches")
    p.add_argument("--draw-workers", type=int, default=0,
                   help="with --device and one GPU: sample the randomizers in this many processes, a batch ahead of "
                        "the render (the same numbers), which also write the files (the same files; default 0: "
                        "draws and encoder threads in this process)")
    p.add_argument("--image-format", choices=("png", "jpg"), default="png",
                   help="RGB images as PNG (default) or, with --device (one GPU), JPEG encoded on the GPU (nvjpeg, "
                        "needs torchvision); the draw processes then write every file")
    p.add_argument("--cpu-jpeg-share", default=None,
                   help="with --image-format jpg: the share of the frames (0 to 1, e.g. 1/3 or 0.25; by frame "
                        "index, so a resumed run writes the same bytes) whose JPEG the draw processes encode on "
                        "the CPU (libjpeg-turbo) while nvjpeg encodes the rest; nvjpeg alone bounds the disk rate "
                        "(default 1/3, for a 16-core host; 0: nvjpeg only)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_viewer_args(p)  # the scene of each frame as it is generated (one process)
    p.set_defaults(func=generate)
