"""``ambulo view``: a scene or robot file in the MuJoCo viewer, or recorded headless to an MP4."""

from __future__ import annotations

import argparse
import difflib
import os
import sys

from .errors import CliError


def _asset_path(target: str) -> str:
    """``target`` as a file: a path, or the file of a bundled asset; ``CliError`` if neither."""
    from ambulo import assets  # noqa: PLC0415
    from ambulo.core.scene import resolve_file  # noqa: PLC0415 - the rule add_robot uses

    try:
        path = resolve_file(target)
    except FileNotFoundError:  # not a path and no bundled asset of that name
        path = None
    if path is not None and os.path.exists(path):
        return path
    close = difflib.get_close_matches(target, assets.names() + ["demo"], n=3)
    fix = (f"did you mean {' or '.join(map(repr, close))}?" if close else
           f"give 'demo', a bundled asset ({', '.join(assets.names())}) or a .xml/.urdf/.usda file")
    raise CliError(f"no file or bundled asset named {target!r}", fix)


def run(args: argparse.Namespace) -> int:
    path = None if args.target == "demo" else _asset_path(args.target)
    if not args.video and not os.environ.get("DISPLAY") and sys.platform.startswith("linux"):
        raise CliError("no display for the interactive viewer",
                       "set DISPLAY, or record headless with --video out.mp4")
    from ambulo.sim import World, add_reference_to_stage  # noqa: PLC0415

    if path is None:
        from ambulo.demo import build_demo_world  # noqa: PLC0415

        world = build_demo_world()[0]
    else:
        world = World()
        world.scene.add_default_ground_plane()
        add_reference_to_stage(usd_path=path, prim_path="/World/Asset")
    world.reset()
    if args.video:
        from ambulo.sim.recorder import Recorder  # noqa: PLC0415

        with Recorder(world, args.video) as rec:
            for _ in range(int(args.seconds / world.get_rendering_dt())):
                world.step()
                rec.capture()
        print(f"wrote {args.video} ({rec.num_frames} frames)")
        return 0
    import mujoco.viewer  # noqa: PLC0415

    mujoco.viewer.launch(world.model, world.engine.get_data(0))
    return 0


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    """Add ``view`` to the ``ambulo`` parser."""
    p = subparsers.add_parser("view", help="open a scene or robot file in the MuJoCo viewer")
    p.add_argument("target", help="'demo', a bundled asset name (jetbot, humanoid, ...) or a file")
    p.add_argument("--video", help="record headless to this MP4 instead of opening a window")
    p.add_argument("--seconds", type=float, default=5.0)
    p.set_defaults(func=run)
