"""Atomic writes leave the old file or the complete new one, never a partial file or a temporary."""

import json

import numpy as np
import pytest

from ambulo.utils.atomic import (
    TMP_MARK, atomic_open, atomic_save_npy, atomic_write_json, atomic_write_text, remove_partial_files,
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


def test_remove_partial_files_deletes_only_temporaries(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / f"000001.png{TMP_MARK}123").write_bytes(b"partial")
    (tmp_path / "sub" / "000000.png").write_bytes(b"done")
    assert remove_partial_files(tmp_path) == 1
    assert [p.name for p in tmp_path.rglob("*") if p.is_file()] == ["000000.png"]
