"""The ``ambulo`` command line: demo, view, bench, and the data/RL commands."""

from __future__ import annotations

import argparse
import sys


def _demo(args) -> int:
    from .demo import run_demo  # noqa: PLC0415

    report = run_demo(seconds=args.seconds, video=None if args.no_video else args.video,
                      progress=not args.quiet)
    for line in report.lines():
        print(line)
    return 0 if report.humanoid_stood else 1


def _view(args) -> int:
    import os  # noqa: PLC0415

    from . import assets  # noqa: PLC0415
    from .sim import World, add_reference_to_stage  # noqa: PLC0415

    target = args.target
    if target == "demo":
        from .demo import build_demo_world  # noqa: PLC0415

        world = build_demo_world()[0]
    else:
        path = target if os.path.exists(target) else assets.path(target)
        world = World()
        world.scene.add_default_ground_plane()
        add_reference_to_stage(usd_path=path, prim_path="/World/Asset")
    world.reset()
    if args.video:
        from .sim.recorder import Recorder  # noqa: PLC0415

        with Recorder(world, args.video) as rec:
            for _ in range(int(args.seconds / world.get_rendering_dt())):
                world.step()
                rec.capture()
        print(f"wrote {args.video} ({rec.num_frames} frames)")
        return 0
    if not os.environ.get("DISPLAY") and sys.platform.startswith("linux"):
        print("no display for the interactive viewer: set DISPLAY, or record with --video out.mp4",
              file=sys.stderr)
        return 2
    import mujoco.viewer  # noqa: PLC0415

    data = world.engine.get_data(0)
    mujoco.viewer.launch(world.model, data)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ambulo", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="Jetbot + humanoid scene, headless, written to an MP4")
    demo.add_argument("--seconds", type=float, default=8.0, help="simulated seconds")
    demo.add_argument("--video", default="out/demo.mp4", help="MP4 to write")
    demo.add_argument("--no-video", action="store_true", help="skip rendering")
    demo.add_argument("--quiet", action="store_true", help="no progress bar")
    demo.set_defaults(func=_demo)

    view = sub.add_parser("view", help="open a scene or robot file in the MuJoCo viewer")
    view.add_argument("target", help="'demo', a bundled asset name (jetbot, humanoid, ...) or a file")
    view.add_argument("--video", help="record headless to this MP4 instead of opening a window")
    view.add_argument("--seconds", type=float, default=5.0)
    view.set_defaults(func=_view)

    for module, adder in (("cli_data", "add_data_commands"), ("cli_rl", "add_rl_commands")):
        try:
            mod = __import__(f"ambulo.{module}", fromlist=[adder])
        except ImportError as err:
            if err.name and err.name.startswith("ambulo"):
                continue  # that part of ambulo is not installed in this checkout
            raise
        getattr(mod, adder)(sub)
    return parser


# optional packages -> the extra that installs them
_EXTRAS = {
    "rsl_rl": "rl", "tensordict": "rl", "tensorboard": "rl", "onnx": "rl", "onnxruntime": "rl",
    "onnxscript": "rl", "gymnasium": "rl", "pycocotools": "data", "ray": "data", "PIL": "data",
    "mujoco_warp": "gpu", "warp": "gpu", "example_robot_data": "robots",
}


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ModuleNotFoundError as err:
        extra = _EXTRAS.get((err.name or "").split(".")[0])
        if extra is None:
            raise
        print(f"ambulo {args.command} needs the package {err.name!r}, which is not installed: "
              f"pip install 'ambulo[{extra}]'", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
