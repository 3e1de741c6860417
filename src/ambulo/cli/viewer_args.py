"""``--viewer web`` and ``--viewer-port``: the flags every command that simulates shares."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from .errors import CliError


def add_viewer_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--viewer", choices=("none", "web"), default="none",
                        help="web: watch it live in a browser (a server on 127.0.0.1, its URL printed)")
    parser.add_argument("--viewer-port", type=int, default=8080,
                        help="TCP port of the web viewer (the next free one if taken)")


def viewer_kind(args: argparse.Namespace) -> str | None:
    """``"web"`` (the viewer package imported, so ``World(viewer="web")`` finds it) or None. A
    namespace built without the viewer flags (a script calling a command's function) means none."""
    if getattr(args, "viewer", "none") == "none":
        return None
    if not 0 < args.viewer_port < 65536:
        raise CliError(f"--viewer-port {args.viewer_port} is not a TCP port", "pass 1-65535, e.g. 8080")
    try:
        import ambulo.viewer  # noqa: F401  (registers viewer="web")
    except ImportError as err:
        raise CliError(f"--viewer web needs viser ({err})", "pip install 'viser==1.1.1'") from None
    return args.viewer


def web_watch(args: argparse.Namespace, *, real_time: bool = False) -> Callable[[Any], Any] | None:
    """What the commands that build their simulation inside a library (``ambulo.rl``,
    ``ambulo.replicator``) take as ``watch``: ``ambulo.viewer.serve`` on what they build, at
    ``--viewer-port`` (None without ``--viewer web``). ``real_time``: the page opens at 1x instead
    of the env's max (``ambulo play``: a rollout is for watching)."""
    if viewer_kind(args) is None:
        return None

    def watch(world_or_env):
        from ambulo.viewer import serve

        viewer = serve(world_or_env, port=args.viewer_port)
        if real_time:
            viewer.set_speed(1.0)
        return viewer

    return watch

