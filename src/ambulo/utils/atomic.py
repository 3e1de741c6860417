"""Atomic file writes: a temporary file in the target's folder, then ``os.replace``.

``os.replace`` is atomic on POSIX, so a process killed at any instant leaves each file
either complete (old or new) or absent, never truncated. ``fsync=True`` also flushes the
data to disk before the rename, so the file survives an OS crash or power loss; that costs
a disk round trip per file, worth it for a checkpoint, not for every frame of a dataset.
Temporaries are named ``<name>.tmp-<pid>``; ``remove_partial_files`` deletes those a killed
run left behind.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import numpy as np

TMP_MARK = ".tmp-"


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, *, fsync: bool = False) -> Iterator[IO[bytes]]:
    """A binary file to write ``path``'s new content into (e.g. with ``torch.save``); it
    replaces ``path`` when the block ends without an exception, else it is deleted."""
    path = Path(path)
    tmp = path.with_name(f"{path.name}{TMP_MARK}{os.getpid()}")
    try:
        with open(tmp, "wb") as f:
            yield f
            if fsync:
                f.flush()
                os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: str | os.PathLike, data: bytes, *, fsync: bool = False) -> None:
    with atomic_open(path, fsync=fsync) as f:
        f.write(data)


def atomic_write_text(path: str | os.PathLike, text: str, *, fsync: bool = False) -> None:
    atomic_write_bytes(path, text.encode(), fsync=fsync)


def atomic_write_json(path: str | os.PathLike, obj: Any, *, indent: int | None = None,
                      sort_keys: bool = True, fsync: bool = False) -> None:
    """``obj`` as JSON: compact without ``indent``, else indented for people to read."""
    separators = (",", ":") if indent is None else None
    atomic_write_text(path, json.dumps(obj, indent=indent, sort_keys=sort_keys, separators=separators),
                      fsync=fsync)


def atomic_save_npy(path: str | os.PathLike, array: np.ndarray, *, fsync: bool = False) -> None:
    with atomic_open(path, fsync=fsync) as f:
        np.save(f, array)


def remove_partial_files(root: str | os.PathLike) -> int:
    """Delete temporaries a killed run left behind under ``root``; returns how many."""
    count = 0
    for tmp in Path(root).rglob(f"*{TMP_MARK}*"):
        tmp.unlink(missing_ok=True)
        count += 1
    return count
