"""``records``: the frame records' journals (one per writer process): torn tails, records that do not
count, frames merged from several journals. The whole runs (a kill, a resume): test_generate.py,
test_parallel.py, test_data_safety.py."""

from __future__ import annotations

import subprocess
import sys

from ambulo.replicator import records
from ambulo.replicator.writers import json_bytes


def _record(index: int, files: dict[str, int]) -> bytes:
    return json_bytes({"frame": index, "file_name": f"rgb/{index:06d}.png", "annotations": [], "files": files})


def _dataset(tmp_path, sizes: dict[int, int]):
    """A dataset folder with frame i's one file ``rgb/NNNNNN.png`` of ``sizes[i]`` bytes."""
    (tmp_path / "frames").mkdir()
    (tmp_path / "rgb").mkdir()
    for index, size in sizes.items():
        (tmp_path / "rgb" / f"{index:06d}.png").write_bytes(b"x" * size)
    return tmp_path


def test_a_torn_tail_is_cut_before_the_next_append(tmp_path):
    """A write cut short (a power loss) leaves the journal without its last newline: the next append
    of that journal's process must not glue its record to the torn bytes."""
    frames = tmp_path / "frames"
    frames.mkdir()
    journal = frames / records.journal_name()
    whole = _record(0, {})
    journal.write_bytes(whole + b"\n" + _record(1, {})[:20])
    assert records.record_lines(frames) == {0: whole}
    records.append_records(frames, [_record(2, {}), _record(3, {})])
    assert journal.read_bytes() == whole + b"\n" + _record(2, {}) + b"\n" + _record(3, {}) + b"\n"
    assert sorted(records.read_records(frames)) == [0, 2, 3]
    # a journal with no newline at all is cut to nothing
    journal.write_bytes(b'{"frame":7,"fi')
    records.append_records(frames, [_record(8, {})])
    assert journal.read_bytes() == _record(8, {}) + b"\n"


def test_a_resume_drops_every_record_that_does_not_count(tmp_path):
    """Before frames are made again, each journal keeps only the lines that parse and whose files have
    the listed sizes, once a frame; its torn tail goes too. A file per record (a dataset of before the
    journals) that does not count is deleted, one that counts is kept."""
    out = _dataset(tmp_path, {0: 5, 1: 3, 2: 4, 3: 6})
    good = _record(0, {"rgb/000000.png": 5})
    journal = out / "frames" / "records-a-1.jsonl"
    journal.write_bytes(b"\n".join([
        good,
        _record(1, {"rgb/000001.png": 9}),  # its file lost bytes
        _record(4, {})[: 25],  # a line cut in half, its newline kept
        _record(0, {"rgb/000000.png": 5}),  # frame 0 again
        b"\0\0\0" + _record(5, {}),  # a power loss's zeros
        b'{"frame":6',  # the torn tail: no newline
    ]))
    other = out / "frames" / "records-b-2.jsonl"
    other.write_bytes(_record(9, {"rgb/000009.png": 1}) + b"\n")  # every line of it stale: the journal goes
    (out / "frames" / "000002.json").write_bytes(_record(2, {"rgb/000002.png": 4}))
    (out / "frames" / "000003.json").write_bytes(_record(3, {"rgb/000003.png": 7}))
    assert set(records.complete_records(out)) == {0, 2}
    assert records.prune_records(out) == {0, 2}
    assert journal.read_bytes() == good + b"\n"
    assert not other.exists() and not (out / "frames" / "000003.json").exists()
    assert (out / "frames" / "000002.json").is_file()
    assert sorted(records.record_lines(out / "frames")) == [0, 2]
    assert records.prune_records(out) == {0, 2} and journal.read_bytes() == good + b"\n"  # nothing more to drop


def test_each_process_appends_to_its_own_journal_and_the_readers_merge_them(tmp_path, gen):
    """Two processes appending at once never share a journal (its name holds the process); the readers
    see every frame, in frame order whatever journal holds it."""
    frames = tmp_path / "frames"
    frames.mkdir()
    code = ("import sys; from ambulo.replicator import records; from ambulo.replicator.writers import json_bytes\n"
            "for i in range(int(sys.argv[1]), 40, 2):\n"
            "    records.append_records(sys.argv[2], [json_bytes({'frame': i, 'files': {}})])\n")
    runs = [subprocess.Popen([sys.executable, "-c", code, str(first), str(frames)], env=gen.env()) for first in (1, 0)]
    assert [run.wait(timeout=60) for run in runs] == [0, 0]
    journals = records.journals(frames)
    assert len(journals) == 2
    for journal, first in zip(sorted(journals, key=lambda p: p.read_bytes()[:12]), (0, 1)):
        assert [records.frame_of_line(line) for line in records.split_journal(journal.read_bytes())[0]] == \
            list(range(first, 40, 2))
    assert list(records.read_records(frames)) == sorted(records.read_records(frames)) == list(range(40))
