"""Atomic writes leave the old file or the complete new one, never a partial file or a temporary."""

import json

import numpy as np
import pytest

from ambulo.utils.atomic import (
    TMP_MARK,
    atomic_open,
    atomic_save_npy,
    atomic_write_json,
    atomic_write_text,
    is_partial_file,
    remove_partial_files,
    temporary_name,
)


def test_a_failed_write_keeps_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "state.bin"
    atomic_write_text(path, "old")
    with pytest.raises(RuntimeError), atomic_open(path, fsync=True) as f:
        f.write(b"half of the new")
        raise RuntimeError("crash while writing")
    assert path.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["state.bin"]


def test_json_and_npy_round_trip(tmp_path):
    atomic_write_json(tmp_path / "compact.json", {"b": 1, "a": [1.5, None]})
    assert (tmp_path / "compact.json").read_text() == '{"a":[1.5,null],"b":1}'
    atomic_write_json(tmp_path / "pretty.json", {"b": 1, "a": 2}, indent=2, sort_keys=False)
    assert (tmp_path / "pretty.json").read_text() == json.dumps({"b": 1, "a": 2}, indent=2)
    array = np.arange(6.0).reshape(2, 3)
    atomic_save_npy(tmp_path / "a.npy", array)
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), array)


def test_remove_partial_files_deletes_only_ambulo_temporaries(tmp_path):
    (tmp_path / "sub").mkdir()
    ours = tmp_path / "sub" / temporary_name("000001.png")
    ours.write_bytes(b"partial")
    users = ["000000.png", "notes.tmp-1", "a.png.tmp-123", f"x{TMP_MARK}1-deadbeef", f".x{TMP_MARK}1-nothex!"]
    for name in users:
        (tmp_path / "sub" / name).write_bytes(b"mine")
    nested = tmp_path / "sub" / "deeper"
    nested.mkdir()
    (nested / temporary_name("a.png")).write_bytes(b"not in the folders given")
    assert remove_partial_files(tmp_path / "sub", tmp_path / "missing") == 1
    assert not ours.exists()
    assert sorted(p.name for p in (tmp_path / "sub").iterdir() if p.is_file()) == sorted(users)
    assert len(list(nested.iterdir())) == 1


def test_temporaries_are_hidden_unique_and_recognised(tmp_path):
    names = {temporary_name("000001.png") for _ in range(100)}
    assert len(names) == 100 and all(n.startswith(".000001.png" + TMP_MARK) and is_partial_file(n) for n in names)
    assert not is_partial_file("000001.png") and not is_partial_file("data.tmp-12")


def test_writes_return_their_size_in_bytes(tmp_path):
    assert atomic_write_text(tmp_path / "a.txt", "héllo") == (tmp_path / "a.txt").stat().st_size == 6
    size = atomic_save_npy(tmp_path / "a.npy", np.zeros((3, 5), np.float32))
    assert size == (tmp_path / "a.npy").stat().st_size


def test_write_bytes_takes_any_buffer_and_a_failed_one_leaves_no_temporary(tmp_path):
    from ambulo.utils.atomic import atomic_write_bytes

    path = tmp_path / "a.bin"
    array = np.arange(7, dtype=np.uint16)
    assert atomic_write_bytes(path, array.data, fsync=True) == 14 == path.stat().st_size
    assert path.read_bytes() == array.tobytes()
    assert atomic_write_bytes(str(path), b"new") == 3 and path.read_bytes() == b"new"
    with pytest.raises(TypeError):
        atomic_write_bytes(path, object())  # not a buffer: fails after the temporary was made
    assert path.read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bin"]


@pytest.mark.parametrize("api", ["open", "bytes"])
def test_fsync_sees_the_whole_content_before_the_rename(tmp_path, monkeypatch, api):
    """Both writers flush through one primitive: the fsync'd temporary already holds every byte
    (a file object's buffer is flushed first), and the rename comes after it."""
    import os

    from ambulo.utils import atomic
    from ambulo.utils.atomic import atomic_write_bytes

    events = []
    real_fsync, real_replace = os.fsync, os.replace
    monkeypatch.setattr(atomic.os, "fsync", lambda fd: events.append(("fsync", os.fstat(fd).st_size)) or real_fsync(fd))
    monkeypatch.setattr(atomic.os, "replace", lambda a, b: events.append(("replace",)) or real_replace(a, b))
    data = bytes(range(250)) * 4  # 1 kB: less than a file object's buffer (st_blksize), so it waits there to be flushed
    path = tmp_path / "a.bin"
    if api == "open":
        with atomic_open(path, fsync=True) as f:
            f.write(data)
    else:
        atomic_write_bytes(path, data, fsync=True)
    assert events == [("fsync", len(data)), ("replace",)]
    assert path.read_bytes() == data


@pytest.mark.parametrize("api", ["open", "bytes"])
def test_a_failed_rename_leaves_no_temporary(tmp_path, api):
    from ambulo.utils.atomic import atomic_write_bytes

    target = tmp_path / "taken"
    (target / "inside").mkdir(parents=True)  # a non-empty folder: the rename onto it fails
    with pytest.raises(OSError):
        if api == "open":
            with atomic_open(target) as f:
                f.write(b"data")
        else:
            atomic_write_bytes(target, b"data")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken"]
