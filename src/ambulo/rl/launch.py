"""``ambulo train TASK --num-gpus N``: the same command as N data-parallel ranks, one GPU each.

What the flag saves a user is torchrun's command line (``torchrun --nproc-per-node N -m ambulo.cli
train ...``, the path ``distributed`` documents and tests): this process starts
``python -m torch.distributed.run --standalone`` (torchrun's module: a free rendezvous port on
this host) with the user's arguments less ``--num-gpus``, waits for it and returns its exit status.
The ranks then run exactly what a hand-written torchrun runs. Ctrl-C reaches the ranks from the
terminal (one process group), each saves its checkpoint as a single-process run does, and this
process waits for them rather than leaving them behind.
"""

from __future__ import annotations

import os
import subprocess
import sys

RANK_ENV = "LOCAL_RANK"
"""Set by torchrun in every rank: a command that sees it is a rank already and launches nothing."""


def without_option(argv: list[str], option: str) -> list[str]:
    """``argv`` less ``option`` and its value (``--opt N`` or ``--opt=N``)."""
    out, skip = [], False
    for token in argv:
        if skip:
            skip = False
        elif token == option:
            skip = True
        elif not token.startswith(option + "="):
            out.append(token)
    return out


def rank_command(argv: list[str], processes: int) -> list[str]:
    """The torchrun command that runs ``ambulo <argv>`` as ``processes`` ranks on this host."""
    return [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc-per-node", str(processes),
            "-m", "ambulo.cli", *argv]


def launch_ranks(argv: list[str], processes: int, env: dict[str, str] | None = None) -> int:
    """Run ``ambulo <argv>`` as ``processes`` ranks (see the module docstring); their exit status."""
    proc = subprocess.Popen(rank_command(argv, processes), env={**os.environ, **(env or {})})
    try:
        return proc.wait()
    except KeyboardInterrupt:  # the ranks got it too: let them save and stop
        return proc.wait()


__all__ = ["RANK_ENV", "launch_ranks", "rank_command", "without_option"]
