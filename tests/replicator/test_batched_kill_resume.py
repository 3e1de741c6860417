"""``ambulo generate --device ... --draw-workers N`` (the GPU path's disk mode) killed mid-run and resumed.

The disk mode commits records after a flush of their files and makes ``annotations.json`` from the
COCO pieces of the frames it commits and the records of the frames an earlier run made
(``coco_file``): a run killed with SIGKILL mid-run and run again must leave the uninterrupted run's
files, ``annotations.json`` byte for byte. On CUDA it is the headline mode (JPEG from nvjpeg); on
Warp's CPU device (slow: each run builds the scene and its processes) PNG. The CUDA run is long
enough (2,000 frames) not to end between the first records and the kill.
"""

from __future__ import annotations

import signal
import subprocess

import pytest
import torch

from ambulo.utils.atomic import TMP_MARK

DEVICES = [
    pytest.param("cuda", "jpg", 16, 2000, marks=pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA"),
                 id="cuda-jpg"),
    pytest.param("cpu", "png", 4, 48, marks=pytest.mark.slow, id="warp-cpu-png"),
]


@pytest.mark.parametrize("device, image_format, worlds, frames", DEVICES)
def test_a_killed_disk_mode_run_resumes_to_the_uninterrupted_result(tmp_path, gen, device, image_format, worlds,
                                                                    frames):
    extra = ("--device", device, "--num-worlds", str(worlds), "--draw-workers", "2", "--image-format", image_format)
    records = tmp_path / "resumed" / "frames"
    victim = gen.start(gen.argv(tmp_path / "resumed", frames, *extra), records, at_least=worlds)
    victim.send_signal(signal.SIGKILL)
    victim.wait()
    done_before = len(gen.records(tmp_path / "resumed"))
    assert worlds <= done_before < frames
    assert not (tmp_path / "resumed" / "annotations.json").exists()
    for name in ("resumed", "straight"):
        subprocess.run(gen.argv(tmp_path / name, frames, *extra), env=gen.env(), check=True, capture_output=True)
    resumed, straight = gen.file_tree(tmp_path / "resumed"), gen.file_tree(tmp_path / "straight")
    assert not [name for name in resumed if TMP_MARK in name]
    assert sorted(resumed) == sorted(straight)
    for name in straight:
        assert resumed[name] == straight[name], name
    assert (tmp_path / "resumed" / "annotations.json").read_bytes() == \
        (tmp_path / "straight" / "annotations.json").read_bytes()
