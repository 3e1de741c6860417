"""``ambulo run script.py [args]``: an Isaac Sim script, unchanged, on ambulo."""

from __future__ import annotations

import argparse

from .errors import CliError
from .viewer_args import add_viewer_args, viewer_kind


def run(args: argparse.Namespace) -> int:
    if args.seconds <= 0:
        raise CliError(f"--seconds {args.seconds} is not positive", "give --seconds above 0")
    viewer = viewer_kind(args)
    from ambulo.isaac import IsaacNameError, run_script
    from ambulo.isaac.runner import ScriptPathError

    try:
        result = run_script(args.script, args.script_args, seconds=args.seconds, viewer=viewer,
                            viewer_port=getattr(args, "viewer_port", 8080))
    except (IsaacNameError, ScriptPathError) as err:
        # anything else raised inside the user's script keeps its traceback, as `python script.py`
        raise CliError(str(err)) from None
    if not args.quiet:
        how = f"{result.ran_sample} loaded and played" if result.ran_sample else "ran"
        print(f"ambulo run: {how}: {result.sim_time_s:.2f} s simulated in {result.physics_steps} physics steps")
    return 0


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    """Add ``run`` to the ``ambulo`` parser."""
    p = subparsers.add_parser(
        "run", help="run an Isaac Sim script unchanged (isaacsim.*/omni.isaac.* imports answered by ambulo)",
        description="Run an Isaac Sim standalone script or extension example (a BaseSample subclass) "
                    "with Isaac's module names answered by ambulo. Flags of `ambulo run` go before the "
                    "script; everything after it is the script's own argv.")
    p.add_argument("--seconds", type=float, default=10.0,
                   help="simulated seconds for a BaseSample's PLAY and for `while simulation_app.is_running()` "
                        "loops (default 10)")
    p.add_argument("--quiet", action="store_true", help="no summary line")
    add_viewer_args(p)  # the script's World, or its Isaac Gym viewer, in a browser
    p.add_argument("script", help="the Isaac Sim script (.py)")
    p.add_argument("script_args", nargs=argparse.REMAINDER, help="arguments passed to the script")
    p.set_defaults(func=run)
