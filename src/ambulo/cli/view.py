"""``ambulo view``: a scene or robot file in the MuJoCo viewer, or recorded headless to an MP4."""

from __future__ import annotations

import argparse
import difflib
import os
import sys

from .errors import CliError, check_output_file, check_seconds
from .viewer_args import add_viewer_args, viewer_kind

_KINDS = (".xml", ".urdf", ".usd", ".usda", ".usdc", ".usdz")
"""File kinds ``ambulo.core.load_spec`` reads."""


def _asset_path(target: str) -> str:
    """``target`` as a file: a path, the stand-in of an Isaac library path, or the file of a
    bundled asset; ``CliError`` if none."""
    from ambulo import assets
    from ambulo.sim.isaac_assets import resolve_asset  # the rule add_reference_to_stage uses

    try:
        path = resolve_asset(target)
    except FileNotFoundError:  # not a path and no bundled asset of that name
        path = None
    if path is not None and os.path.isdir(path):
        files = sorted(f for f in os.listdir(path) if os.path.splitext(f)[1].lower() in _KINDS)[:3]
        fix = (f"give a file in it, e.g. {os.path.join(target, files[0])}" if files else
               f"give a scene or robot file ({', '.join(_KINDS)})")
        raise CliError(f"{target!r} is a folder", fix)
    if path is not None and os.path.exists(path):
        kind = os.path.splitext(path)[1].lower()
        if kind not in _KINDS:
            raise CliError(f"{target!r} is not a scene or robot file (unknown kind {kind or 'without suffix'!r})",
                           f"give an MJCF, URDF or USD file ({', '.join(_KINDS)})")
        return path
    close = difflib.get_close_matches(target, assets.names() + ["demo"], n=3)
    fix = (f"did you mean {' or '.join(map(repr, close))}?" if close else
           f"give 'demo', a bundled asset ({', '.join(assets.names())}) or a .xml/.urdf/.usda file")
    raise CliError(f"no file or bundled asset named {target!r}", fix)


def run(args: argparse.Namespace) -> int:
    path = None if args.target == "demo" else _asset_path(args.target)
    check_seconds(args.seconds)
    if args.video:
        check_output_file(args.video, "--video")
    viewer = viewer_kind(args)
    if viewer is not None and args.video:
        raise CliError("--viewer web shows the scene live; --video records it headless", "pass one of them")
    if viewer is not None:
        return _serve(path, viewer, args)
    if args.renderer != "raster" and not args.video:
        raise CliError(f"--renderer {args.renderer} draws --video frames; the interactive viewer is MuJoCo's own",
                       "add --video out.mp4, or leave --renderer out")
    if not args.video and not os.environ.get("DISPLAY") and sys.platform.startswith("linux"):
        raise CliError("no display for the interactive viewer",
                       "set DISPLAY, or record headless with --video out.mp4")
    world = _world(path)
    world.reset()
    if args.video:
        from ambulo.sim.recorder import Recorder

        with Recorder(world, args.video, renderer=args.renderer) as rec:
            for _ in range(int(args.seconds / world.get_rendering_dt())):
                world.step()
                rec.capture()
        print(f"wrote {args.video} ({rec.num_frames} frames)")
        return 0
    import mujoco.viewer

    mujoco.viewer.launch(world.model, world.engine.get_data(0))
    return 0


def _serve(path: str | None, viewer: str, args: argparse.Namespace) -> int:
    """The scene simulated at real time (the page's speed) in a browser, ``--seconds`` of it."""
    world = _world(path, viewer=viewer, viewer_port=getattr(args, "viewer_port", 8080))
    try:
        world.reset()
        for _ in range(int(round(args.seconds / world.get_rendering_dt()))):
            world.step(render=False)
    finally:
        world.viewer.close()
    return 0


def _world(path: str | None, **world_args):
    from ambulo.sim import World, add_reference_to_stage

    if path is None:
        from ambulo.demo import build_demo_world

        return build_demo_world(**world_args)[0]
    world = World(**world_args)
    world.scene.add_default_ground_plane()
    add_reference_to_stage(usd_path=path, prim_path="/World/Asset")
    return world


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    """Add ``view`` to the ``ambulo`` parser."""
    p = subparsers.add_parser("view", help="open a scene or robot file in the MuJoCo viewer")
    p.add_argument("target", help="'demo', a bundled asset name (jetbot, humanoid, ...) or a file")
    p.add_argument("--video", help="record headless to this MP4 instead of opening a window")
    p.add_argument("--seconds", type=float, default=5.0, help="simulated seconds (--video, --viewer web)")
    p.add_argument("--renderer", choices=("raster", "pbr"), default="raster",
                   help="what draws the --video frames: raster (MuJoCo) or pbr (Filament: PBR materials, shadows)")
    add_viewer_args(p)
    p.set_defaults(func=run)
