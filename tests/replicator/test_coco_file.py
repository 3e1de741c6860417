"""``coco_file``: annotations.json concatenated from frame pieces is ``merge_coco``'s file, byte for byte.

The pieces are made where the records are (the GPU disk path's processes) and the file only
concatenates them with the running annotation ids, so it must not matter which frames came as
pieces and which were read back from their records (a resumed run has both), nor that a frame has
no annotation (the separators), and a NaN must still give the standard library's file.
"""

from __future__ import annotations

import contextlib
import io
import json

import pytest
from pycocotools.coco import COCO

from ambulo.replicator.coco import merge_coco
from ambulo.replicator.coco_file import frame_piece, record_piece, write_annotations
from ambulo.replicator.writers import json_bytes

CATEGORIES = ["box", "cylinder"]
INFO = {"description": "t", "version": "1.0", "gl_renderer": "test", "seed": 3}


def _annotation(k: int, iid: int) -> dict:
    """An annotation as ``coco.frame_annotations`` makes one (floats with long digits, nested lists)."""
    return {"category_id": 1 + k % 2, "bbox": [k + 0.5, 2.0, 3.0, 4.25], "area": 12 + k,
            "segmentation": {"size": [4, 6], "counts": "52O0N"}, "iscrowd": 0, "instance_id": iid,
            "prim_path": f"/World/objects/box_{iid}", "bbox_3d": {"center_w": [0.1 * k, 1 / 3, 2e-7]}}


def _records(tmp_path, counts: list[int], encode=json_bytes) -> list[dict]:
    """Frame records with ``counts[i]`` annotations each, written as ``FrameWriter`` writes them
    (``encode``d) by two writer processes: the even frames in one journal, the odd ones in another,
    each in descending frame order (the frames' order is the readers' to make)."""
    (tmp_path / "frames").mkdir()
    records = []
    for i, count in enumerate(counts):
        records.append({"frame": i, "file_name": f"rgb/{i:06d}.jpg", "width": 6, "height": 4,
                        "annotations": [_annotation(i + k, k + 1) for k in range(count)], "camera": {"k": [1.5]},
                        "randomization": {}, "files": {f"rgb/{i:06d}.jpg": 10}})
    for worker in (0, 1):
        lines = [encode(record) for record in records[worker::2]][::-1]
        if lines:
            (tmp_path / "frames" / f"records-host-{100 + worker}.jsonl").write_bytes(b"\n".join(lines) + b"\n")
    return records


def _merged(tmp_path, frames: int) -> bytes:
    return json_bytes(merge_coco(tmp_path / "frames", frames, CATEGORIES, INFO))


@pytest.mark.parametrize("counts", [[0, 3, 0, 2, 1], [2, 0, 0, 4], [0, 0], [3]], ids=str)
@pytest.mark.parametrize("given", ["none", "all", "odd"])
def test_the_file_from_pieces_and_records_is_merge_cocos(tmp_path, counts, given):
    records = _records(tmp_path, counts)
    chosen = {"none": [], "all": range(len(counts)), "odd": range(1, len(counts), 2)}[given]
    # pieces from the records in memory (as the writer processes make them), not read back
    pieces = {i: frame_piece(i, records[i]) for i in chosen}
    path = tmp_path / "annotations.json"
    write_annotations(path, tmp_path / "frames", len(counts), CATEGORIES, INFO, pieces)
    assert path.read_bytes() == _merged(tmp_path, len(counts))
    with contextlib.redirect_stdout(io.StringIO()):
        coco = COCO(str(path))
    assert [a["id"] for a in coco.dataset["annotations"]] == list(range(1, sum(counts) + 1))
    assert sorted(coco.getImgIds()) == list(range(1, len(counts) + 1))
    # the two journals' records merge in frame order
    assert [image["frame"] for image in coco.dataset["images"]] == list(range(len(counts)))


def test_a_piece_in_memory_is_the_piece_read_back_from_its_record(tmp_path):
    records = _records(tmp_path, [2, 0, 1])
    for i, record in enumerate(records):
        assert frame_piece(i, record) == record_piece(tmp_path / "frames", i)


def test_a_piece_is_used_as_it_is(tmp_path):
    # the file takes a given piece rather than the record (what makes it cheap): a piece that
    # differs from its record shows in the file
    records = _records(tmp_path, [1, 1])
    other = dict(records[1], file_name="rgb/elsewhere.jpg")
    write_annotations(tmp_path / "a.json", tmp_path / "frames", 2, CATEGORIES, INFO, {1: frame_piece(1, other)})
    assert [i["file_name"] for i in json.loads((tmp_path / "a.json").read_text())["images"]] == \
        ["rgb/000000.jpg", "rgb/elsewhere.jpg"]


def test_a_nan_gives_jsons_file_as_before(tmp_path):
    def with_a_nan(record):  # frame 1's, as json writes it (NaN)
        if record["frame"] != 1:
            return json_bytes(record)
        record["annotations"][0]["bbox_3d"]["center_w"][0] = float("nan")
        return json.dumps(record, separators=(",", ":")).encode()

    records = _records(tmp_path, [1, 2], with_a_nan)
    assert frame_piece(1, records[1]) is None and frame_piece(0, records[0]) is not None
    path = tmp_path / "annotations.json"
    write_annotations(path, tmp_path / "frames", 2, CATEGORIES, INFO, {0: frame_piece(0, records[0])})
    assert path.read_bytes() == _merged(tmp_path, 2) and b"NaN" in path.read_bytes()
