"""``ambulo demo``: the Jetbot + humanoid scene, headless, written to an MP4."""

from __future__ import annotations

import argparse

from .errors import check_output_file, check_seconds
from .viewer_args import add_viewer_args, viewer_kind


def run(args: argparse.Namespace) -> int:
    check_seconds(args.seconds)
    if not args.no_video:
        check_output_file(args.video, "--video")
    viewer = viewer_kind(args)
    from ambulo.demo import run_demo

    report = run_demo(seconds=args.seconds, video=None if args.no_video else args.video,
                      progress=not args.quiet, renderer=args.renderer, viewer=viewer, viewer_port=getattr(args, "viewer_port", 8080))
    for line in report.lines():
        print(line)
    return 0 if report.humanoid_stood else 1


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    """Add ``demo`` to the ``ambulo`` parser."""
    p = subparsers.add_parser("demo", help="Jetbot + humanoid scene, headless, written to an MP4")
    p.add_argument("--seconds", type=float, default=8.0, help="simulated seconds")
    p.add_argument("--video", default="out/demo.mp4", help="MP4 to write")
    p.add_argument("--no-video", action="store_true", help="skip rendering")
    p.add_argument("--renderer", choices=("raster", "pbr"), default="raster",
                   help="what draws the video: raster (MuJoCo) or pbr (Filament: PBR materials, shadows)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_viewer_args(p)
    p.set_defaults(func=run)
