"""How ``ambulo`` commands fail on bad input: one line ``ambulo <command>: error: <problem>; <fix>``
on stderr and exit status 2, never a traceback."""

from __future__ import annotations

import argparse
import sys

EXIT_USAGE = 2
"""Exit status of a command given bad input (argparse's too)."""

EXTRAS = {
    "rsl_rl": "rl", "tensordict": "rl", "tensorboard": "rl", "onnx": "rl", "onnxruntime": "rl",
    "onnxscript": "rl", "gymnasium": "rl", "pycocotools": "data", "ray": "data", "PIL": "data",
    "isal": "data", "cloudpickle": "data",
    "mujoco_warp": "gpu", "warp": "gpu", "example_robot_data": "robots",
}
"""Optional top-level packages -> the ``ambulo[extra]`` that installs them."""


class CliError(Exception):
    """Bad user input: ``problem`` says what is wrong, ``fix`` what to do about it."""

    def __init__(self, problem: str, fix: str = ""):
        self.problem, self.fix = problem, fix
        super().__init__(f"{problem}; {fix}" if fix else problem)


def missing_extra(err: ModuleNotFoundError) -> CliError | None:
    """The ``CliError`` naming the extra that installs the missing module, or ``None`` when
    the module is not one of ambulo's optional packages (then it is a bug: re-raise)."""
    extra = EXTRAS.get((err.name or "").split(".")[0])
    if extra is None:
        return None
    return CliError(f"needs the package {err.name!r}, which is not installed",
                    f"pip install 'ambulo[{extra}]'")


def missing_file(err: FileNotFoundError) -> CliError:
    """A ``FileNotFoundError`` as one line (ambulo's own messages already carry their fix)."""
    if err.filename is not None:  # raised by the OS: "[Errno 2] No such file or directory"
        return CliError(f"no such file or folder: {str(err.filename)!r}", "check the path")
    return CliError(str(err).replace("\n", " "))


def error_line(command: str, err: Exception) -> str:
    return f"ambulo {command}: error: {err}"


def report(command: str, err: Exception) -> int:
    """Print ``err`` as the one error line of ``ambulo <command>``; return the exit status."""
    print(error_line(command, err), file=sys.stderr)
    return EXIT_USAGE


class ArgumentParser(argparse.ArgumentParser):
    """argparse with a one-line error (``<prog>: error: <problem>; see <prog> --help``) instead of
    usage + error, and an epilog that may be computed only when help is shown (``lazy_epilog``,
    so listing the tasks does not import torch for every command)."""

    lazy_epilog = None

    def error(self, message: str):  # noqa: D102 - argparse's hook
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}; see `{self.prog} --help`\n")

    def format_help(self) -> str:
        if self.lazy_epilog is not None:
            self.epilog = self.lazy_epilog()
        return super().format_help()


__all__ = ["EXIT_USAGE", "EXTRAS", "ArgumentParser", "CliError", "error_line", "missing_extra",
           "missing_file", "report"]
