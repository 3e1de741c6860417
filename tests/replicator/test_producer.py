"""run_frames keeps the heap that existed before it out of the garbage collector's scans, and
gives the collector back its state afterwards (its own or one the caller froze)."""

from __future__ import annotations

import gc

import pytest

from ambulo import replicator as rep
from ambulo.replicator import producer as producer_module
from ambulo.replicator.records import read_records
from ambulo.replicator.writers import FrameWriter, prepare_dirs


@pytest.fixture(scope="module")
def small_producer():
    config = rep.example_config(32, 24)
    producer = rep.FrameProducer(config)
    yield producer
    producer.close()


def _frozen_counts_while_writing(monkeypatch, producer, out, frames) -> list[int]:
    seen = []

    def write(self, index, capture, table, log):
        seen.append(gc.get_freeze_count())
        return FrameWriter.write(self, index, capture, table, log)

    monkeypatch.setattr(producer_module, "FrameWriter", type("Probe", (FrameWriter,), {"write": write}))
    prepare_dirs(out, producer.config.writer)
    rep.run_frames(producer.config, out, 0, frames, producer=producer)
    return seen


def test_the_heap_is_frozen_during_the_run_and_handed_back_after(tmp_path, monkeypatch, small_producer):
    assert gc.get_freeze_count() == 0
    before = gc.get_freeze_count()
    alive = len(gc.get_objects())
    seen = _frozen_counts_while_writing(monkeypatch, small_producer, tmp_path, [0, 1, 2])
    assert len(seen) == 3 and min(seen) >= alive * 0.9  # the objects alive before the run (a few died since)
    assert gc.get_freeze_count() == before == 0
    assert 2 in read_records(tmp_path / "frames")


def test_a_heap_the_caller_froze_stays_frozen(tmp_path, monkeypatch, small_producer):
    gc.freeze()
    try:
        frozen = gc.get_freeze_count()
        seen = _frozen_counts_while_writing(monkeypatch, small_producer, tmp_path, [0, 1])
        assert len(seen) == 2 and min(seen) >= frozen * 0.9
        assert gc.get_freeze_count() >= frozen * 0.9  # not unfrozen by the run (a few frozen objects died)
    finally:
        gc.unfreeze()


def test_a_camera_jitter_sets_the_whole_pose_so_skipping_the_reset_changes_no_frame(small_producer):
    """The producer skips the camera's pose reset when a CameraJitter of it sets the pose every frame:
    frames made in any order with and without the reset have the same camera pose (pixels follow it)."""
    producer = small_producer
    assert producer._jitter_sets_pose  # the example config jitters its camera
    cam_pos, cam_quat = producer.engine.model_field("cam_pos"), producer.engine.model_field("cam_quat")
    poses = {}
    for reset in (False, True):
        producer._jitter_sets_pose = not reset
        try:
            for index in (3, 0, 3, 7, 1):  # out of order: each frame after a different one
                producer.randomize(2, index)
                camera = producer.capture()["camera"]
                pose = (camera["pos_w"].tolist(), camera["quat_w_opengl"].tolist(),
                        cam_pos[0, producer.camera.cam_id].tolist(), cam_quat[0, producer.camera.cam_id].tolist())
                poses.setdefault(index, []).append(pose)
        finally:
            producer._jitter_sets_pose = True
    for index, seen in poses.items():
        assert all(pose == seen[0] for pose in seen), index
    assert poses[3][0] != poses[0][0]  # the jitter moved the camera between frames


def test_the_producers_tight_boxes_and_masks_from_column_runs_are_the_cameras_own(small_producer):
    """The producer asks the camera for everything but the tight boxes and adds them (and the COCO
    masks) from one pass of column runs: the same boxes, pixel counts, ids and RLEs as the camera's
    own row-order tight boxes and the RLEs of the instance image."""
    import numpy as np

    from ambulo.replicator.coco import instance_rles

    producer = small_producer
    assert producer._boxes_from_runs  # the dataset's annotators: the fast path is on
    for index in range(6):
        producer.randomize(4, index)
        capture = producer.capture()
        producer.camera.begin_capture(0)  # the camera's own, with its tight boxes, on the same state
        own = producer.camera.end_capture()
        np.testing.assert_array_equal(capture["instance_segmentation"], own["instance_segmentation"])
        got, want = capture["bounding_box_2d_tight"], own["bounding_box_2d_tight"]
        assert list(got) == list(want)
        for key in want:
            np.testing.assert_array_equal(got[key], want[key])
            assert got[key].dtype == want[key].dtype
        ids = want["instance_id"]
        assert [r["counts"] for r in capture["coco_rles"](ids)] == \
            [r["counts"] for r in instance_rles(own["instance_segmentation"], ids)]
