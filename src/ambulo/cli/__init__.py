"""The ``ambulo`` command line: demo, view, generate, and the RL commands (train, play, export, eval).

Each command lives in its own module (``demo``, ``view``, ``data``, ``rl``) with an
``add_commands(subparsers)`` and imports what it runs only when it runs. Bad input (an
unknown task, a missing run folder or file, a bad ``--env-cfg``) ends the command with one
line ``ambulo <command>: error: <problem>; <fix>`` on stderr and exit status 2.
"""

from __future__ import annotations

import argparse

from . import data, demo, rl, view
from .errors import ArgumentParser, CliError, missing_extra, missing_file, report
from ..utils.overrides import OverrideError, apply_overrides

_COMMAND_MODULES = (demo, view, data, rl)


def build_parser() -> argparse.ArgumentParser:
    """The ``ambulo`` argument parser with every command; ``args.func(args)`` runs one."""
    parser = ArgumentParser(prog="ambulo", description="ambulo: robotics simulation, synthetic data "
                            "and RL on MuJoCo. `ambulo COMMAND --help` tells more.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in _COMMAND_MODULES:
        module.add_commands(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``ambulo`` with ``argv`` (default ``sys.argv[1:]``); return the exit status."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except CliError as err:
        return report(args.command, err)
    except ModuleNotFoundError as err:
        extra = missing_extra(err)
        if extra is None:
            raise
        return report(args.command, extra)
    except FileNotFoundError as err:
        return report(args.command, missing_file(err))


__all__ = ["CliError", "OverrideError", "apply_overrides", "build_parser", "main"]
