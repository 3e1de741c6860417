"""``ambulo generate``: make a labelled, randomized dataset (COCO + PNGs) from a config or the example scene.

    ambulo generate --frames 100 --out data/ --seed 0              # the warehouse example
    ambulo generate my_config.py --frames 1000 --out data/ --workers 4

A CONFIG file is Python defining ``config()`` (or ``CONFIG``) that returns an
``ambulo.replicator.DatasetConfig``. Re-running the same command finishes an
interrupted dataset; the same seed gives byte-identical files.
"""

from __future__ import annotations

import argparse
import dataclasses
import runpy
import sys
from pathlib import Path


def load_config(path: str | None, width: int | None = None, height: int | None = None):
    from ambulo import replicator as rep

    if path is None:
        config = rep.example_config()
    else:
        file = Path(path)
        if not file.is_file():
            raise SystemExit(f"ambulo generate: config file {path!r} not found")
        namespace = runpy.run_path(str(file))
        if "config" in namespace and callable(namespace["config"]):
            config = namespace["config"]()
        elif "CONFIG" in namespace:
            config = namespace["CONFIG"]
        else:
            raise SystemExit(f"ambulo generate: {path} must define config() or CONFIG returning a DatasetConfig")
        if not isinstance(config, rep.DatasetConfig):
            raise SystemExit(f"ambulo generate: {path} gave {type(config).__name__}, not a DatasetConfig")
    if width or height:
        camera = dataclasses.replace(config.camera, width=width or config.camera.width,
                                     height=height or config.camera.height)
        config = dataclasses.replace(config, camera=camera)
    return config


def run_generate(args: argparse.Namespace) -> int:
    from ambulo import replicator as rep

    config = load_config(args.config, args.width, args.height)
    path = rep.generate(config, args.out, num_frames=args.frames, seed=args.seed, workers=args.workers,
                        show_progress=not args.quiet)
    print(f"wrote {path}")
    return 0


def add_data_commands(subparsers) -> None:
    """Register ``generate`` on an ``argparse`` subparsers object (called by ``ambulo.cli``)."""
    p = subparsers.add_parser("generate", help="generate a labelled synthetic dataset (COCO)",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("config", nargs="?", default=None, help="Python file defining config(); default: example scene")
    p.add_argument("--frames", type=int, default=100, help="number of frames (default 100)")
    p.add_argument("--out", type=Path, required=True, help="output folder (resumed if it holds a partial run)")
    p.add_argument("--seed", type=int, default=0, help="randomization seed (default 0)")
    p.add_argument("--workers", type=int, default=1, help="Ray workers; >1 runs shards in parallel")
    p.add_argument("--width", type=int, default=None, help="override the camera width (px)")
    p.add_argument("--height", type=int, default=None, help="override the camera height (px)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run_generate)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="ambulo")
    add_data_commands(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
