"""Reading frame-record journals: ``frames/records-<host>-<pid>.jsonl`` of a dataset folder.

The format of ``ambulo generate``'s records (written by ``ambulo.replicator.records``, which owns the
contract: appends, torn tails, pruning on resume): each line of a journal is one frame's record as compact
JSON starting with its ``"frame"`` key; a line counts only with its newline; where a frame has several
lines, the last of the journals by name wins. Datasets written before the journals hold one
``frames/NNNNNN.json`` file a record, read the same. The reading side lives here, below the apps, because
more than the writer reads records: the detector's dataset reads each frame's camera for its height channel
(``detection.dataset``), and detection may not import the replicator (a peer app).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
from pathlib import Path

try:  # msgspec's decoder: a fraction of json's time on a dataset's records
    from msgspec import DecodeError as _DecodeError
    from msgspec.json import decode as _msgspec_decode
except ImportError:
    _msgspec_decode = None

JOURNAL_FILE = re.compile(r"records-[A-Za-z0-9._-]+\.jsonl")
"""The whole name of every journal."""
LEGACY_RECORD = re.compile(r"(\d{6,})\.json")
"""A record of a dataset written before the journals: ``frames/NNNNNN.json``."""
_FRAME_PREFIX = re.compile(rb'\{"frame":(\d+)[,}]')
"""A record line's frame index without decoding the line: ``write_frame_files``' dict starts with it."""


def journals(frames_dir: str | os.PathLike) -> list[Path]:
    """The journals in ``frames_dir``, by name."""
    with contextlib.suppress(FileNotFoundError):
        return sorted(Path(entry.path) for entry in os.scandir(frames_dir)
                      if JOURNAL_FILE.fullmatch(entry.name) and entry.is_file(follow_symlinks=False))
    return []


def legacy_records(frames_dir: str | os.PathLike) -> list[tuple[int, Path]]:
    """(frame index, path) of each ``NNNNNN.json`` record (datasets written before the journals), by index."""
    with contextlib.suppress(FileNotFoundError):
        return sorted((int(m.group(1)), Path(entry.path)) for entry in os.scandir(frames_dir)
                      if (m := LEGACY_RECORD.fullmatch(entry.name)) and entry.is_file(follow_symlinks=False))
    return []


def split_journal(data: bytes) -> tuple[list[bytes], bytes]:
    """(the complete lines, the torn tail: the bytes after the last newline, b'' when none) of a journal."""
    *lines, tail = data.split(b"\n")
    return lines, tail


def frame_of_line(line: bytes) -> int | None:
    """The frame index a record line is for, read from its first key (None: not a record's start)."""
    match = _FRAME_PREFIX.match(line)
    return int(match.group(1)) if match else None


def record_lines(frames_dir: str | os.PathLike) -> dict[int, bytes]:
    """Frame index -> its record's line (undecoded; the last complete one of the frame in the journals
    by name, else its ``NNNNNN.json``) of every frame with one, in frame order. Whether a line parses and its files are
    whole is ``complete_records``' question: in a run's own folder after ``prune_records``, they do."""
    found: dict[int, bytes] = {index: path.read_bytes() for index, path in legacy_records(frames_dir)}
    for journal in journals(frames_dir):
        lines, _ = split_journal(journal.read_bytes())
        for line in lines:
            index = frame_of_line(line)
            if index is not None:
                found[index] = line
    return dict(sorted(found.items()))


def read_json(data: bytes):
    """JSON ``data`` as Python values: msgspec's decoder, json's for what msgspec refuses (NaN and
    Infinity, which ``writers.json_bytes`` leaves to json)."""
    if _msgspec_decode is not None:
        try:
            return _msgspec_decode(data)
        except _DecodeError:
            pass
    return json.loads(data)


def read_records(frames_dir: str | os.PathLike) -> dict[int, dict]:
    """Frame index -> its record (decoded) of every frame of ``record_lines`` whose line parses, in
    frame order."""
    records = {}
    for index, line in record_lines(frames_dir).items():
        with contextlib.suppress(ValueError, UnicodeDecodeError):
            record = read_json(line)
            if isinstance(record, dict):
                records[index] = record
    return records


def read_record(frames_dir: str | os.PathLike, index: int) -> dict:
    """Frame ``index``'s record; ``FileNotFoundError`` when no line of it parses."""
    record = read_records(frames_dir).get(index)
    if record is None:
        raise FileNotFoundError(f"{frames_dir}: no record of frame {index} in its journals ({JOURNAL_FILE.pattern})")
    return record
