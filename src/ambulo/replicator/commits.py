"""The GPU disk mode's records: a batch's records on disk only after one flush of its files.

The draw processes write a batch's data files (``batched_disk``) and hand back its frame records.
A frame is done for a resumed run when its record parses and its files have the sizes it lists
(``records.complete_records``), so a record must not reach the disk before the data it points
to: the records are appended to the journal after a flush of the data (``FrameWriter.flush``: one ``syncfs`` on
Linux). Flushing a batch as it finishes and holding its shared block until then (the first disk
mode) put every flush on the render's path: the device waited for the storage once a batch.
``BatchCommits`` takes that off the path with two threads:

- the *settle* thread waits for each batch's processes, in batch order, and frees its block at
  once (the files are in the page cache; the flush does not read the block);
- the *commit* thread makes every batch finished since its last flush durable with one more
  flush, then writes their records (group commit: a slow flush covers several batches, and its
  wait overlaps the next batches' rendering and writing).

A crash at any point leaves records only for frames whose files were flushed: a resumed run
makes the others again. Each part may hand back its frames' COCO pieces too (``coco_file``): they
are kept (``pieces``) only for frames whose records were written, for ``annotations.json``.
"""

from __future__ import annotations

import collections
import contextlib
import queue
import threading
import time


class BatchCommits:
    """Settles and commits batches (see the module docstring). ``writer``: a ``FrameWriter`` whose
    batch never fills (only ``flush`` writes records); ``free``: where a batch's block goes back
    once its processes are done; ``progress(n)``: called with each commit's frame count.
    ``times`` gets ``wait_writes_s``, ``commit_s``, ``commits`` and the parts' own seconds.
    ``pieces`` (a dict, or None: not kept) gets each committed frame's ``coco_file.FramePiece``."""

    def __init__(self, writer, free: queue.Queue, progress=None, pieces: dict | None = None):
        self.writer, self.free, self.progress, self.pieces = writer, free, progress, pieces
        self.times: collections.Counter = collections.Counter()
        self.failed: list[BaseException] = []
        self._written: queue.Queue = queue.Queue()  # (block, futures) in batch order, then None
        self._done: queue.Queue = queue.Queue()  # each batch's ((index, record)s, pieces), then None
        self._threads = [threading.Thread(target=self._settle, name="ambulo-settle", daemon=True),
                         threading.Thread(target=self._commit, name="ambulo-commit", daemon=True)]
        for thread in self._threads:
            thread.start()

    def put(self, block, futures) -> None:
        """A batch handed to the processes: ``futures`` give (records, seconds, pieces) each:
        [(index, record)] (a dict or ``writers.EncodedRecord``), {stage: seconds}, {index: piece}."""
        self._written.put((block, futures))

    def close(self) -> None:
        """Wait until every batch put is settled and committed (or failed)."""
        self._written.put(None)
        for thread in self._threads:
            thread.join()

    def _settle(self) -> None:
        while (item := self._written.get()) is not None:
            block, futures = item
            records: list = []
            pieces: dict = {}
            start = time.perf_counter()
            try:
                for future in futures:
                    part, seconds, part_pieces = future.result()
                    records.extend(part)
                    pieces.update(part_pieces)
                    self.times.update(seconds)
            except BaseException as err:  # the other parts' frames are kept; the run stops
                self.failed.append(err)
            finally:
                self.times["wait_writes_s"] += time.perf_counter() - start
                self._done.put((records, pieces))
                self.free.put(block)
        self._done.put(None)

    def _commit(self) -> None:
        finished, broken = False, False
        while not finished:
            batches = [self._done.get()]
            with contextlib.suppress(queue.Empty):
                while True:  # the batches that finished during the last flush: one flush for all
                    batches.append(self._done.get_nowait())
            finished = batches[-1] is None
            batches = [batch for batch in batches if batch is not None]
            records = [record for batch, _ in batches for record in batch]
            if not records or broken:  # after a failed flush nothing more is committed (see below)
                continue
            for index, record in records:
                self.writer.add(index, record)
            start = time.perf_counter()
            try:
                self.writer.flush()  # the files first, then the records
            except BaseException as err:  # no record of these frames: a resumed run makes them again
                # and none of any later batch: a flush that failed once may report success next
                # time with data lost (Linux reports a writeback error once), so none is trusted
                self.failed.append(err)
                broken = True
                continue
            finally:
                self.times["commit_s"] += time.perf_counter() - start
            self.times["commits"] += 1
            if self.pieces is not None:  # the records are written: their pieces stand for them
                for _, pieces in batches:
                    self.pieces.update(pieces)
            if self.progress is not None:
                self.progress(len(records))


__all__ = ["BatchCommits"]
