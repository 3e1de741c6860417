"""Generation is a pure function of (config, seed, frame): determinism, resume after a kill, Ray shards.

Local worker processes: test_parallel.py."""

import filecmp
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from ambulo import replicator as rep

SIZE = (160, 120)
SRC = str(Path(rep.__file__).resolve().parents[2])


def tree(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_same_seed_gives_identical_files_and_another_seed_does_not(tmp_path, small_config):
    config = small_config()
    for name, seed in (("a", 1), ("b", 1), ("c", 2)):
        rep.generate(config, tmp_path / name, num_frames=4, seed=seed, show_progress=False)
    a, b, c = (tree(tmp_path / n) for n in "abc")
    assert a == b
    assert a["rgb/000000.png"] != c["rgb/000000.png"]


def test_a_frame_regenerates_alone_from_its_log(tmp_path, small_config):
    config = small_config()
    rep.generate(config, tmp_path, num_frames=3, seed=9, show_progress=False)
    import json

    record = json.loads((tmp_path / "frames" / "000002.json").read_text())
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


def _cli(out: Path, frames: int, *extra) -> list[str]:
    return [sys.executable, "-m", "ambulo.cli", "generate", "--frames", str(frames), "--out", str(out),
            "--seed", "4", "--width", str(SIZE[0]), "--height", str(SIZE[1]), "--quiet", *extra]


def test_killed_run_resumes_to_the_uninterrupted_result(tmp_path):
    env = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}
    frames = 60
    victim = subprocess.Popen(_cli(tmp_path / "resumed", frames), env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    records = tmp_path / "resumed" / "frames"
    deadline = time.time() + 120
    while time.time() < deadline and victim.poll() is None:
        if records.is_dir() and len(list(records.glob("*.json"))) >= 5:
            break
        time.sleep(0.02)
    assert victim.poll() is None, "the run finished before it could be killed: raise `frames`"
    victim.send_signal(signal.SIGKILL)
    victim.wait()
    done_before = len(list(records.glob("*.json")))
    assert 5 <= done_before < frames
    subprocess.run(_cli(tmp_path / "resumed", frames), env=env, check=True, capture_output=True)
    subprocess.run(_cli(tmp_path / "straight", frames), env=env, check=True, capture_output=True)
    resumed, straight = tree(tmp_path / "resumed"), tree(tmp_path / "straight")
    assert not [name for name in resumed if ".tmp-" in name]
    assert resumed == straight


def test_ray_workers_produce_the_same_dataset(tmp_path, small_config):
    pytest.importorskip("ray")
    config = small_config()
    rep.generate(config, tmp_path / "serial", num_frames=10, seed=3, show_progress=False)
    rep.generate(config, tmp_path / "ray", num_frames=10, seed=3, workers=2, show_progress=False, backend="ray")
    serial, sharded = tree(tmp_path / "serial"), tree(tmp_path / "ray")
    assert serial.keys() == sharded.keys()
    assert filecmp.cmp(tmp_path / "serial" / "annotations.json", tmp_path / "ray" / "annotations.json", shallow=False)
    assert serial == sharded
