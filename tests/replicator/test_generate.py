"""Generation is a pure function of (config, seed, frame): determinism, resume after a kill, Ray shards.

Local worker processes: test_parallel.py."""

import filecmp
import signal
import subprocess

import numpy as np
import pytest

from ambulo import replicator as rep
from ambulo.utils.atomic import TMP_MARK


def test_same_seed_gives_identical_files_and_another_seed_does_not(tmp_path, small_config, gen):
    config = small_config()
    for name, seed in (("a", 1), ("b", 1), ("c", 2)):
        rep.generate(config, tmp_path / name, num_frames=4, seed=seed, show_progress=False)
    a, b, c = (gen.file_tree(tmp_path / n) for n in "abc")
    assert a == b
    assert a["rgb/000000.png"] != c["rgb/000000.png"]


def test_a_frame_regenerates_alone_from_its_log(tmp_path, small_config):
    config = small_config()
    rep.generate(config, tmp_path, num_frames=3, seed=9, show_progress=False)
    record = rep.records.read_record(tmp_path / "frames", 2)
    producer = rep.FrameProducer(config)
    try:
        producer.replay(record["randomization"])
        replayed = producer.capture()
        log = producer.randomize(9, 2)  # drawing frame 2 directly, without frames 0 and 1
        drawn = producer.capture()
    finally:
        producer.close()
    assert log == record["randomization"]
    assert np.array_equal(replayed["rgb"], drawn["rgb"])
    from PIL import Image

    assert np.array_equal(np.asarray(Image.open(tmp_path / "rgb" / "000002.png")), drawn["rgb"])


@pytest.mark.parametrize("torn", [False, True])
def test_killed_run_resumes_to_the_uninterrupted_result(tmp_path, gen, torn):
    """``torn``: the killed run's journal also ends in a torn record (half of a line: a write cut short
    by a power loss), which the resumed run drops; annotations.json is the straight run's, byte for byte."""
    frames = 60
    records = tmp_path / "resumed" / "frames"
    victim = gen.start(gen.argv(tmp_path / "resumed", frames), records)
    victim.send_signal(signal.SIGKILL)
    victim.wait()
    done_before = rep.records.count_records(records)
    assert 5 <= done_before < frames
    if torn:
        (journal,) = rep.records.journals(records)
        lines = journal.read_bytes().split(b"\n")
        with journal.open("ab") as f:  # a record of the next frame, cut in the middle
            f.write(lines[0].replace(b'{"frame":0,', b'{"frame":%d,' % (frames - 1))[: len(lines[0]) // 2])
        assert rep.records.count_records(records) == done_before
    subprocess.run(gen.argv(tmp_path / "resumed", frames), env=gen.env(), check=True, capture_output=True)
    subprocess.run(gen.argv(tmp_path / "straight", frames), env=gen.env(), check=True, capture_output=True)
    resumed, straight = gen.file_tree(tmp_path / "resumed"), gen.file_tree(tmp_path / "straight")
    assert not [name for name in resumed if TMP_MARK in name]
    assert resumed == straight


def test_ray_workers_produce_the_same_dataset(tmp_path, small_config, gen):
    pytest.importorskip("ray")
    config = small_config()
    rep.generate(config, tmp_path / "serial", num_frames=10, seed=3, show_progress=False)
    rep.generate(config, tmp_path / "ray", num_frames=10, seed=3, workers=2, show_progress=False, backend="ray")
    serial, sharded = gen.file_tree(tmp_path / "serial"), gen.file_tree(tmp_path / "ray")
    assert serial.keys() == sharded.keys()
    assert filecmp.cmp(tmp_path / "serial" / "annotations.json", tmp_path / "ray" / "annotations.json", shallow=False)
    assert serial == sharded
