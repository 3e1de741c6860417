"""The ``ambulo`` command line: demo, view, generate, the RL commands (train, play, export, eval),
``run`` (an Isaac Sim script, unchanged), ``plan`` (footsteps on a map, optionally walked in
simulation), ``bridge`` (a ROS 2 node), ``map`` (visual odometry and a TSDF map) and ``navigate``
(the autonomous navigator).

Each command lives in its own module (``demo``, ``view``, ``data``, ``rl``, ``run``, ``plan``,
``bridge``, ``perception``, ``navigate``) with an
``add_commands(subparsers)`` and imports what it runs only when it runs. Bad input (an
unknown task, a missing or unwritable file, a bad value, a bad ``--env-cfg``) ends the command
with one line ``ambulo <command>: error: <problem>; <fix>`` on stderr and exit status 2; Ctrl-C
with one line and status 130. Any other exception is a bug and keeps its traceback, and
``--debug`` (before or after the command) shows the traceback of every error.
"""

from __future__ import annotations

import argparse
import difflib
import re
import sys

from ..utils.overrides import OverrideError, apply_overrides
from . import bridge, data, demo, detection, navigate, perception, plan, rl, run, view
from .errors import EXIT_INTERRUPTED, ArgumentParser, CliError, expected_error, report

_COMMAND_MODULES = (demo, view, data, detection, rl, run, plan, bridge, perception, navigate)
_DEBUG_HELP = "show the full traceback of any error (for bug reports)"


def build_parser() -> argparse.ArgumentParser:
    """The ``ambulo`` argument parser with every command; ``args.func(args)`` runs one."""
    parser = ArgumentParser(prog="ambulo", description="ambulo: robotics simulation, synthetic data "
                            "and RL on MuJoCo. `ambulo COMMAND --help` tells more.")
    parser.add_argument("--debug", action="store_true", help=_DEBUG_HELP)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in _COMMAND_MODULES:
        module.add_commands(sub)
    for command in sub.choices.values():  # `ambulo view x --debug` works too
        command.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=_DEBUG_HELP)
    parser.commands = sub.choices
    return parser


def _unrecognized(parser: argparse.ArgumentParser, args: argparse.Namespace, extra: list[str]) -> None:
    """Refuse arguments the command does not know in one line from the command's own parser (so it
    points at `ambulo <command> --help`), naming the nearest option for a misspelt one."""
    command = parser.commands.get(getattr(args, "command", None), parser)
    known = [o for action in command._actions for o in action.option_strings]
    guesses = [f"{o}: did you mean {near[0]}?" for o in extra if o.startswith("-")
               if (near := difflib.get_close_matches(o.split("=")[0], known, n=1, cutoff=0.75))]
    command.error(f"unrecognized arguments: {' '.join(extra)}" + (f" ({'; '.join(guesses)})" if guesses else ""))


_NEGATIVE_VALUES = re.compile(r"^-\d*\.?\d+(e-?\d+)?(,-?\d*\.?\d+(e-?\d+)?)*$")
"""``-4,-2.5`` or ``-1e-3``: a value, not an option, though it starts with '-'."""


def _join_negative_values(parser: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """``--start -4,-2`` -> ``--start=-4,-2``: argparse reads a token starting with '-' that is not a
    plain number as an option, so a coordinate list with a negative first value failed with
    "expected one argument". Only after an option of the command that takes a value; a command
    that passes the rest on (``run``'s script arguments) is left alone."""
    name = next((t for t in argv if t in parser.commands), None)
    command = parser.commands.get(name)
    if command is None or any(a.nargs == argparse.REMAINDER for a in command._actions):
        return argv
    takes_value = {o for a in command._actions for o in a.option_strings if a.nargs != 0}
    out: list[str] = []
    for token in argv:
        if out and out[-1] in takes_value and _NEGATIVE_VALUES.match(token):
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


def main(argv: list[str] | None = None) -> int:
    """Run ``ambulo`` with ``argv`` (default ``sys.argv[1:]``); return the exit status."""
    parser = build_parser()
    argv = _join_negative_values(parser, list(sys.argv[1:] if argv is None else argv))
    args, extra = parser.parse_known_args(argv)
    if extra:
        _unrecognized(parser, args, extra)
    args.argv = argv  # what a command that re-launches itself passes on (`train --num-gpus`)
    if args.debug:
        return int(args.func(args) or 0)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print(f"ambulo {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as err:
        known = expected_error(err)
        if known is None:  # a bug: keep the traceback
            raise
        return report(args.command, known)


__all__ = ["CliError", "OverrideError", "apply_overrides", "build_parser", "main"]
