"""Frame records: one append-only journal per writer process, ``frames/records-<host>-<pid>.jsonl``.

A frame's record (``writers.write_frame_files``' dict: its COCO image and annotations, camera, randomizer
log and every file it wrote with its size in bytes) is what makes the frame's files count: a frame is
done for a resumed run when its record parses and each file has the listed size. A record is one line
of compact JSON (``writers.json_bytes``: never a raw newline, strings escape theirs), appended to its
writer's journal after the frame's files were written (with ``WriterCfg.fsync``, after they reached the
disk). A file per record was the fourth file a frame created: on the 2-core VM's ext4 a create cost
0.47-0.51 ms of CPU after many creates and deletes (0.08 on a fresh one), ~5 % of an annotated frame
(``benchmarks/results/cpu-2026-11-29-replicator-s10-ab.md``); an append to an open journal costs no create.

The contract, as with a file per record:

- a torn record never counts: a line counts only with its newline, and a journal's last bytes without
  one (a write cut short, or a power loss's zeros) are cut off before the next append (``append_records``);
- a line that does not parse, or whose files do not have the listed sizes, does not count either, and
  a resumed run drops every such line before it makes those frames again (``prune_records``), so that
  files being rewritten never have a record (the file-per-record writer deleted the old record first);
- two processes never append to one journal: the name holds the host and the process id, and appends
  of one process's threads are serialized by a lock; a journal is only ever rewritten (``prune_records``)
  by a run's parent before its writers start.

A frame has at most one line that counts (a frame is made again only when it had none); readers take
the last line of a frame that parses where there are several (a benchmark writing the same frames
twice). Datasets written before the journals (``frames/NNNNNN.json``, one file per record) read the
same: such a file is one more record (a journal's line for the frame comes first).
"""

from __future__ import annotations

import os
import re
import socket
import threading
from collections.abc import Iterator
from pathlib import Path

from ambulo.utils.atomic import atomic_write_bytes
from ambulo.utils.frame_journal import (
    JOURNAL_FILE,
    LEGACY_RECORD,
    frame_of_line,
    journals,
    legacy_records,
    read_json,
    read_record,
    read_records,
    record_lines,
    split_journal,
)

_locks: dict[str, threading.Lock] = {}
_locks_lock = threading.Lock()


def journal_name() -> str:
    """This process's journal: ``records-<host>-<pid>.jsonl`` (unique among the processes writing at
    once, on one machine or on several sharing the folder: Ray)."""
    host = re.sub(r"[^A-Za-z0-9.-]", "-", socket.gethostname()) or "host"
    return f"records-{host}-{os.getpid()}.jsonl"


def _lock_for(path: str) -> threading.Lock:
    with _locks_lock:
        return _locks.setdefault(path, threading.Lock())


def append_records(frames_dir: str | os.PathLike, lines: list[bytes], fsync: bool = False) -> None:
    """Append ``lines`` (records as compact JSON, no newline) to this process's journal in ``frames_dir``,
    one newline after each, in one write; ``fsync``: the journal flushed to disk before it is closed.
    A torn tail (bytes after the last newline) is cut off first: it never parses, and a line appended
    after it would be glued to it."""
    if not lines:
        return
    path = os.path.join(os.fspath(frames_dir), journal_name())
    data = b"\n".join(lines) + b"\n"
    with _lock_for(path):
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_APPEND | getattr(os, "O_BINARY", 0), 0o666)
        try:
            _cut_torn_tail(fd)
            with memoryview(data) as view:
                done = 0
                while done < len(data):
                    done += os.write(fd, view[done:])
            if fsync:
                os.fsync(fd)
        finally:
            os.close(fd)


def _cut_torn_tail(fd: int, block: int = 1 << 16) -> None:
    """Truncate the file after its last newline (to nothing without one). Reads at ``lseek`` offsets
    (``os.pread`` is not on Windows); the appends that follow go to the end whatever the offset."""
    size = os.fstat(fd).st_size
    if size == 0 or _read_at(fd, size - 1, 1) == b"\n":
        return
    end = size
    while end > 0:
        start = max(0, end - block)
        newline = _read_at(fd, start, end - start).rfind(b"\n")
        if newline >= 0:
            os.ftruncate(fd, start + newline + 1)
            return
        end = start
    os.ftruncate(fd, 0)


def _read_at(fd: int, offset: int, count: int) -> bytes:
    os.lseek(fd, offset, os.SEEK_SET)
    chunks = []
    while count > 0 and (chunk := os.read(fd, count)):
        chunks.append(chunk)
        count -= len(chunk)
    return b"".join(chunks)


def count_records(frames_dir: str | os.PathLike) -> int:
    """How many frames have a complete record line (not checked further: a progress count)."""
    return len(record_lines(frames_dir))


def _whole(out: Path, line: bytes) -> tuple[int, dict] | None:
    """(index, record) when ``line`` parses as a record whose files all have the listed sizes."""
    try:
        record = read_json(line)
        files = record["files"]
        if all(os.stat(os.path.join(out, relpath)).st_size == size for relpath, size in files.items()):
            return int(record["frame"]), record
    except (OSError, ValueError, KeyError, TypeError, AttributeError, UnicodeDecodeError):
        pass
    return None


def _entries(out: Path) -> Iterator[tuple[Path, bool, list[bytes], bytes]]:
    """(path, is a journal, its complete lines, torn tail) of every record source in ``out/frames``."""
    frames_dir = out / "frames"
    for _, path in legacy_records(frames_dir):
        yield path, False, [path.read_bytes()], b""
    for journal in journals(frames_dir):
        lines, tail = split_journal(journal.read_bytes())
        yield journal, True, lines, tail


def complete_records(out: str | os.PathLike) -> dict[int, dict]:
    """Frame index -> record of every frame of dataset ``out`` that is whole: a record line that
    parses, every file it lists with that size (a ``stat`` each: no file is read but the journals)."""
    out = Path(out)
    done: dict[int, dict] = {}
    for _, _, lines, _ in _entries(out):
        for line in lines:
            whole = _whole(out, line)
            if whole is not None:
                done[whole[0]] = whole[1]
    return done


def prune_records(out: str | os.PathLike, fsync: bool = True) -> set[int]:
    """Drop every record of dataset ``out`` that does not count, and return the frames that are whole.

    A journal with a line that does not parse, lists a file of another size, repeats a frame already
    kept, or with a torn tail, is rewritten (atomically; ``fsync``: flushed first) with the lines that
    count; an ``NNNNNN.json`` that does not count is deleted. Call before writing frames again (a run's
    start, before its writers): a frame made again then has no record while its files are rewritten."""
    out = Path(out)
    done: set[int] = set()
    for path, is_journal, lines, tail in _entries(out):
        kept = []
        for line in lines:
            whole = _whole(out, line)
            if whole is not None and whole[0] not in done:
                done.add(whole[0])
                kept.append(line)
        if not kept:
            path.unlink()
        elif is_journal and (len(kept) < len(lines) or tail):
            atomic_write_bytes(path, b"\n".join(kept) + b"\n", fsync=fsync)
    return done


__all__ = ["JOURNAL_FILE", "LEGACY_RECORD", "append_records", "complete_records", "count_records", "frame_of_line",
           "journal_name", "journals", "prune_records", "read_json", "read_record", "read_records", "record_lines",
           "split_journal"]
