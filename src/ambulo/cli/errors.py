"""How ``ambulo`` commands fail on bad input: one line ``ambulo <command>: error: <problem>; <fix>``
on stderr and exit status 2, never a traceback.

``expected_error`` says which exceptions are bad input (then it gives the line to print) and
which are bugs (``None``: ``main`` lets the traceback through). ``ambulo --debug`` shows the
traceback of every error.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

EXIT_USAGE = 2
"""Exit status of a command given bad input (argparse's too)."""

EXIT_INTERRUPTED = 130
"""Exit status after Ctrl-C (128 + SIGINT, as shells report it)."""

EXTRAS = {
    "rsl_rl": "rl", "tensordict": "rl", "tensorboard": "rl", "onnx": "rl", "onnxruntime": "rl",
    "onnxscript": "rl", "gymnasium": "rl", "pycocotools": "data", "ray": "data", "PIL": "data",
    "isal": "data", "cloudpickle": "data",
    "mujoco_warp": "gpu", "warp": "gpu", "example_robot_data": "robots",
    "cv2": "perception", "open3d": "perception", "evo": "perception", "skimage": "perception",
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


_OS_FIXES = {
    PermissionError: "check its permissions, or choose a path you may write to",
    IsADirectoryError: "give a file path, not a folder",
    NotADirectoryError: "a part of the path is a file, not a folder: fix the path",
    FileExistsError: "a file stands where a folder is needed: remove it or choose another path",
}


def os_error(err: OSError) -> CliError | None:
    """An unwritable or unreadable path as one line, or ``None`` for other OS errors."""
    fix = next((fix for kind, fix in _OS_FIXES.items() if isinstance(err, kind)), None)
    if fix is None:
        return None
    name = err.filename if err.filename is not None else "a path"
    return CliError(f"cannot use {str(name)!r}: {(err.strerror or str(err)).lower()}", fix)


def expected_error(err: BaseException) -> CliError | None:
    """``err`` as the one-line ``CliError`` a user sees, if it is bad input rather than a bug:
    ambulo's own checks (``CliError``, ``InvalidValueError``, ``OverrideError``, ``AssetError``),
    no OpenGL or Vulkan to render with or no ffmpeg to encode with, a missing file or optional package, an unwritable path. ``None`` for anything else."""
    from ..core.importers import AssetError
    from ..utils.checks import InvalidValueError
    from ..utils.overrides import OverrideError

    if isinstance(err, CliError):
        return err
    if isinstance(err, (InvalidValueError, OverrideError, AssetError)):
        return CliError(" ".join(str(err).split()))  # MuJoCo's parser messages span lines
    gl = sys.modules.get("ambulo.render.gl")  # loaded if a render was tried; not imported for other errors
    if gl is not None and isinstance(err, gl.NoOpenGLError):
        return CliError(err.problem, err.fix)
    pbr = sys.modules.get("ambulo.render.pbr")  # loaded if the pbr tier was asked for
    if pbr is not None and isinstance(err, pbr.NoVulkanError):
        return CliError(err.problem, err.fix)
    video = sys.modules.get("ambulo.render.video")  # loaded if a video was written
    if video is not None and isinstance(err, video.VideoError):
        return CliError(err.problem, err.fix)
    if isinstance(err, ModuleNotFoundError):
        return missing_extra(err)
    if isinstance(err, FileNotFoundError):
        return missing_file(err)
    if isinstance(err, OSError):
        return os_error(err)
    return None


def check_output_file(path: str | os.PathLike, flag: str) -> Path:
    """``path`` as a file a command may write, or ``CliError`` before any work is done: its
    folder is created if missing and a probe file is written there (permission bits alone do
    not tell, e.g. for root on a read-only file system)."""
    file = Path(path).expanduser()
    if file.is_dir():
        raise CliError(f"{flag} {str(path)!r} is a folder", f"give a file path, e.g. {file / 'out.mp4'}")
    try:
        file.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=file.parent, prefix=".ambulo-probe-"):
            pass
    except OSError as err:
        known = os_error(err)
        fix = known.fix if known is not None else "choose another path"
        where = err.filename if err.filename and ".ambulo-probe-" not in str(err.filename) else file.parent
        raise CliError(f"{flag} {str(path)!r} cannot be written: {str(where)!r}: "
                       f"{(err.strerror or str(err)).lower()}", fix) from None
    return file


def check_seconds(value: float, flag: str = "--seconds") -> float:
    """A duration flag as a finite number of seconds > 0, or ``CliError``."""
    if not value > 0 or value == float("inf"):  # also refuses nan, which compares false
        raise CliError(f"{flag} {value} is not a positive, finite duration", f"give {flag} above 0, e.g. {flag} 5")
    return value


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

    def error(self, message: str):  # argparse's hook
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}; see `{self.prog} --help`\n")

    def format_help(self) -> str:
        if self.lazy_epilog is not None:
            self.epilog = self.lazy_epilog()
        return super().format_help()


__all__ = ["EXIT_INTERRUPTED", "EXIT_USAGE", "EXTRAS", "ArgumentParser", "CliError", "check_output_file",
           "check_seconds", "error_line", "expected_error", "missing_extra", "missing_file", "os_error",
           "report"]
