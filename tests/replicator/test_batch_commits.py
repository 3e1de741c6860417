"""``commits.BatchCommits``: the GPU disk mode's records reach the disk only after their files' flush.

A record on disk must point to flushed data (a resumed run trusts it), yet the flush must not hold
the render: a batch's block is free once its files are written, batches that finish during a flush
share the next one, and after a failed flush nothing more is committed.
"""

from __future__ import annotations

import concurrent.futures as cf
import queue
import sys
import threading
import time

import pytest

from ambulo.replicator import records, writers
from ambulo.replicator.commits import BatchCommits
from ambulo.replicator.writers import FrameWriter, WriterCfg, prepare_dirs


def _batch(indices, error=None) -> list[cf.Future]:
    """One part's future: the (index, record) pairs a draw process hands back, its seconds and its
    frames' COCO pieces (here, a stand-in naming the frame), or its error."""
    future = cf.Future()
    if error is None:
        future.set_result(([(i, {"frame": i, "files": {f"rgb/{i:06d}.jpg": 3}}) for i in indices],
                           {"part_write_s": 0.5}, {i: f"piece {i}" for i in indices}))
    else:
        future.set_exception(error)
    return [future]


def _records(root) -> set[int]:
    return set(records.record_lines(root / "frames"))


def _wait(condition) -> None:
    deadline = time.monotonic() + 20
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


@pytest.fixture
def flushes(monkeypatch):
    """``syncfs`` replaced: each call records the frame records on disk at that moment, and waits
    for ``gate`` (a slow disk); ``fail`` makes the next call raise."""
    state = {"seen": [], "gate": threading.Event(), "fail": None}

    def sync(path):
        state["seen"].append(_records(path))
        state["gate"].wait()
        if state["fail"] is not None:
            err, state["fail"] = state["fail"], None
            raise err

    monkeypatch.setattr(writers, "can_sync_filesystem", lambda: True)
    monkeypatch.setattr(writers, "sync_filesystem", sync)
    return state


def _commits(root, progress=None, pieces=None):
    cfg = WriterCfg(outputs=("coco",), fsync=True)
    prepare_dirs(root, cfg)
    free: queue.Queue = queue.Queue()
    return BatchCommits(FrameWriter(root, cfg, batch=sys.maxsize), free, progress, pieces), free


def test_records_follow_their_flush_and_blocks_are_freed_before_it(tmp_path, flushes):
    done = []
    commits, free = _commits(tmp_path, done.append)
    commits.put("block0", _batch([0, 1]))
    _wait(lambda: len(flushes["seen"]) == 1)  # the first flush started, and waits for the disk
    commits.put("block1", _batch([2, 3]))
    commits.put("block2", _batch([4]))
    _wait(lambda: free.qsize() == 3)  # every block is free again while the flush still runs
    assert _records(tmp_path) == set()  # and no record is on disk before it ends
    flushes["gate"].set()
    commits.close()
    assert not commits.failed
    # the two batches that finished during the first flush shared the second; each flush saw
    # only the records of the batches before it
    assert flushes["seen"] == [set(), {0, 1}] and done == [2, 3]
    assert _records(tmp_path) == {0, 1, 2, 3, 4}
    assert commits.times["commits"] == 2 and commits.times["part_write_s"] == 1.5


def test_a_failed_flush_writes_no_record_then_or_later(tmp_path, flushes):
    commits, free = _commits(tmp_path)
    flushes["fail"] = OSError(5, "Input/output error")
    commits.put("block0", _batch([0, 1]))
    _wait(lambda: len(flushes["seen"]) == 1)
    flushes["gate"].set()
    _wait(lambda: commits.failed)
    commits.put("block1", _batch([2]))  # a later flush might succeed with the earlier data lost
    commits.close()
    assert isinstance(commits.failed[0], OSError) and _records(tmp_path) == set()
    assert free.qsize() == 2


def test_a_failed_part_keeps_the_other_batches(tmp_path, flushes):
    flushes["gate"].set()
    commits, free = _commits(tmp_path)
    commits.put("block0", _batch([0], error=RuntimeError("encoder died")))
    commits.put("block1", _batch([1, 2]))
    commits.close()
    assert isinstance(commits.failed[0], RuntimeError) and _records(tmp_path) == {1, 2}
    assert free.qsize() == 2


def test_pieces_are_kept_for_the_committed_frames_only(tmp_path, flushes):
    # annotations.json takes a frame's piece instead of reading its record: only a frame whose
    # record was written may have one (a resumed run reads the others' records)
    pieces = {}
    commits, _ = _commits(tmp_path, pieces=pieces)
    commits.put("block0", _batch([0, 1]))
    _wait(lambda: len(flushes["seen"]) == 1)
    assert pieces == {}  # not before its records are on disk
    flushes["gate"].set()
    _wait(lambda: _records(tmp_path) == {0, 1})
    _wait(lambda: len(pieces) == 2)
    flushes["fail"] = OSError(5, "Input/output error")
    commits.put("block1", _batch([2]))
    commits.close()
    assert commits.failed and _records(tmp_path) == {0, 1} and pieces == {0: "piece 0", 1: "piece 1"}


def test_encoded_records_are_written_as_they_are(tmp_path, flushes):
    # the GPU disk mode's processes encode each record (writers.encode_record): the bytes written
    # are json_bytes(record), and a flush without syncfs flushes the folders it lists
    flushes["gate"].set()
    record = {"frame": 4, "files": {"rgb/000004.jpg": 3, "depth/000004.png": 5}, "x": [0.1, 1 / 3]}
    encoded = writers.encode_record(record)
    assert encoded.folders == ("depth", "rgb")
    future = cf.Future()
    future.set_result(([(4, encoded)], {}, {}))
    commits, _ = _commits(tmp_path)
    commits.put("block0", [future])
    commits.close()
    assert records.record_lines(tmp_path / "frames") == {4: writers.json_bytes(record)}
