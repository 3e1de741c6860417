"""``ambulo generate``: make a labelled, randomized dataset (COCO + PNGs) from a config or the example scene.

    ambulo generate --frames 100 --out data/ --seed 0              # the warehouse example
    ambulo generate my_config.py --frames 1000 --out data/ --workers 4
    RAY_ADDRESS=auto ambulo generate my_config.py --frames 100000 --out /shared/data --workers 64

A CONFIG file is Python defining ``config()`` (or ``CONFIG``) that returns an
``ambulo.replicator.DatasetConfig``. Re-running the same command finishes an
interrupted dataset; the same seed gives byte-identical files.
"""

from __future__ import annotations

import argparse
import dataclasses
import runpy
from pathlib import Path

from .errors import CliError

_CONFIG_FIX = "give a Python file whose config() or CONFIG is an ambulo.replicator.DatasetConfig"


def load_config(path: str | None, width: int | None = None, height: int | None = None):
    """The ``DatasetConfig`` of Python file ``path`` (the example scene's for ``None``), with its
    camera resized to ``width`` x ``height`` where given. ``CliError`` on a bad file."""
    from ambulo import replicator as rep  # noqa: PLC0415

    if path is None:
        config = rep.example_config()
    else:
        file = Path(path)
        if not file.is_file():
            raise CliError(f"config file {path!r} not found",
                           "check the path, or leave it out for the example scene")
        namespace = runpy.run_path(str(file))
        if "config" in namespace and callable(namespace["config"]):
            config = namespace["config"]()
        elif "CONFIG" in namespace:
            config = namespace["CONFIG"]
        else:
            raise CliError(f"{path} defines neither config() nor CONFIG", _CONFIG_FIX)
        if not isinstance(config, rep.DatasetConfig):
            raise CliError(f"{path} gave a {type(config).__name__}, not a DatasetConfig", _CONFIG_FIX)
    if width or height:
        camera = dataclasses.replace(config.camera, width=width or config.camera.width,
                                     height=height or config.camera.height)
        config = dataclasses.replace(config, camera=camera)
    return config


def generate(args: argparse.Namespace) -> int:
    from ambulo import replicator as rep  # noqa: PLC0415

    for flag in ("frames", "workers", "width", "height"):
        value = getattr(args, flag)
        if value is not None and value < 1:
            raise CliError(f"--{flag} {value} is not positive", f"give --{flag} 1 or more")
    config = load_config(args.config, args.width, args.height)
    path = rep.generate(config, args.out, num_frames=args.frames, seed=args.seed, workers=args.workers,
                        show_progress=not args.quiet, backend="ray" if args.ray else "auto")
    print(f"wrote {path}")
    return 0


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    """Add ``generate`` to the ``ambulo`` parser."""
    p = subparsers.add_parser("generate", help="generate a labelled synthetic dataset (COCO)",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("config", nargs="?", default=None, help="Python file defining config(); default: example scene")
    p.add_argument("--frames", type=int, default=100, help="number of frames (default 100)")
    p.add_argument("--out", type=Path, required=True, help="output folder (resumed if it holds a partial run)")
    p.add_argument("--seed", type=int, default=0, help="randomization seed (default 0)")
    p.add_argument("--workers", type=int, default=None,
                   help="processes rendering in parallel (default: one per CPU, fewer for short runs)")
    p.add_argument("--ray", action="store_true",
                   help="run the workers on Ray (also when RAY_ADDRESS is set): for several machines sharing --out")
    p.add_argument("--width", type=int, default=None, help="override the camera width (px)")
    p.add_argument("--height", type=int, default=None, help="override the camera height (px)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=generate)
