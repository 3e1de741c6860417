"""``generate(device=...)``: dataset frames rendered many per launch on MuJoCo Warp.

The batched path must make the CPU path's dataset, label for label: the same randomized scene
per frame index (the same draws), boxes within a pixel of the rasterizer's (pycocotools reads
both), a resumable folder, and a fingerprint that keeps the two paths' images apart. The
per-pixel work (instance ids, tight boxes, pixel counts) runs on the device, checked here
against the CPU annotator on hand-made images. ``cuda`` needs a GPU (the GPU suite runs it);
Warp's CPU device runs the same code as a slow case (its first kernel compile takes minutes).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from ambulo import replicator as rep
from ambulo.replicator.batched import device_tight_boxes
from ambulo.replicator.generate import generate
from ambulo.replicator.manifest import DatasetFolderError
from ambulo.replicator.records import read_records, record_lines
from ambulo.sensors.annotators import tight_boxes

DEVICES = [
    pytest.param("cuda", marks=pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")),
    pytest.param("cpu", marks=pytest.mark.slow, id="warp-cpu"),
]


def test_device_boxes_equal_the_cpu_annotators_boxes_on_every_image():
    rng = np.random.default_rng(0)
    images = np.zeros((3, 12, 17), np.int64)
    images[0, 2:5, 3:9] = 1  # a rectangle: box (3, 2, 8, 4), 18 pixels
    images[0, 7, 16] = 2  # one pixel in the last column
    images[1] = rng.integers(0, 4, size=(12, 17))  # noise over instances 1-3
    images[2, 11, 0] = 3  # image 2: only instance 3, bottom-left corner
    boxes, pixels = device_tight_boxes(torch.as_tensor(images), 3)
    assert boxes.shape == (3, 3, 4) and pixels.shape == (3, 3)
    for n in range(3):
        want_boxes, want_pixels = tight_boxes(images[n], 3)
        np.testing.assert_array_equal(boxes[n].numpy(), want_boxes)
        np.testing.assert_array_equal(pixels[n].numpy(), want_pixels)
    np.testing.assert_array_equal(boxes[0, 0].numpy(), [3, 2, 8, 4])  # by hand
    assert pixels[0].tolist() == [18, 1, 0] and boxes[0, 2].tolist() == [-1, -1, -1, -1]
    assert boxes[2, 2].tolist() == [0, 11, 0, 11]


def _by_instance(annotations: dict) -> dict:
    """{(image_id, instance_id): (bbox, area)} of a COCO file."""
    return {(a["image_id"], a["instance_id"]): (a["bbox"], a["area"]) for a in annotations["annotations"]}


@pytest.mark.parametrize("device, draw_workers", [
    *(pytest.param(p.values[0], 0, marks=p.marks, id=p.id) for p in DEVICES),
    # the disk mode: files written on the draw processes, records committed after a flush (batched_disk)
    pytest.param("cuda", 2, marks=pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA"),
                 id="cuda-disk-mode"),
])
def test_batched_dataset_has_the_cpu_paths_labels_and_resumes(device, draw_workers, tmp_path):
    from pycocotools.coco import COCO

    frames, seed = 6, 3
    cpu = generate(rep.example_config(160, 120), tmp_path / "cpu", frames, seed=seed, show_progress=False)
    # 4 worlds for 6 frames: a full batch and a partial one
    gpu = generate(rep.example_config(160, 120), tmp_path / "gpu", frames, seed=seed, show_progress=False,
                   device=device, num_worlds=4, draw_workers=draw_workers)
    a, b = COCO(str(cpu)), COCO(str(gpu))  # pycocotools reads both
    assert sorted(a.getImgIds()) == sorted(b.getImgIds()) == list(range(1, frames + 1))
    want, got = _by_instance(json.loads(cpu.read_text())), _by_instance(json.loads(gpu.read_text()))
    # objects a few pixels across may fall either side of the visibility threshold; the rest match
    clear = [key for key, (_, area) in want.items() if area >= 40]
    assert len(clear) >= 3 * frames
    for key in clear:
        assert key in got, f"object {key} of the CPU dataset is missing from the batched one"
        np.testing.assert_allclose(got[key][0], want[key][0], atol=1.0, err_msg=str(key))
    # the scene per frame is the CPU path's: the same randomization log, frame by frame
    cpu_records, gpu_records = (read_records(tmp_path / name / "frames") for name in ("cpu", "gpu"))
    for i in range(frames):
        cpu_log, gpu_log = cpu_records[i]["randomization"], gpu_records[i]["randomization"]
        assert gpu_log["objects"] == cpu_log["objects"] and gpu_log["lights"] == cpu_log["lights"]
    # resumable: a finished dataset is kept as it is, and more frames extend it
    before = record_lines(tmp_path / "gpu" / "frames")[2]
    generate(rep.example_config(160, 120), tmp_path / "gpu", frames + 2, seed=seed, show_progress=False,
             device=device, num_worlds=4, draw_workers=draw_workers)
    assert record_lines(tmp_path / "gpu" / "frames")[2] == before
    assert len(COCO(str(tmp_path / "gpu" / "annotations.json")).getImgIds()) == frames + 2
    # never mixed: the CPU path refuses to add rasterized frames to a ray-cast dataset
    with pytest.raises(DatasetFolderError, match="image_source"):
        generate(rep.example_config(160, 120), tmp_path / "gpu", frames + 2, seed=seed, show_progress=False)


def test_batched_path_refuses_what_it_cannot_do(tmp_path):
    config = rep.example_config(64, 48)
    with pytest.raises(ValueError, match="--workers"):
        generate(config, tmp_path / "a", 2, device="cpu", workers=2, show_progress=False)
    with pytest.raises(ValueError, match="num-worlds"):
        generate(config, tmp_path / "b", 2, device="cpu", num_worlds=0, show_progress=False)


@pytest.mark.parametrize("device", DEVICES)
def test_in_memory_batches_hold_the_written_datasets_boxes(device, tmp_path):
    from ambulo.replicator.batched import BatchedFrameProducer

    frames, seed = 5, 7
    path = generate(rep.example_config(96, 72), tmp_path / "d", frames, seed=seed, show_progress=False,
                    device=device, num_worlds=4)
    written = _by_instance(json.loads(path.read_text()))
    producer = BatchedFrameProducer(rep.example_config(96, 72), num_worlds=4, device=device)
    seen = 0
    for batch in producer.batches(seed, list(range(frames))):
        assert batch["rgb"].dtype == torch.uint8 and batch["rgb"].shape[1:] == (72, 96, 3)
        assert batch["rgb"].device.type == torch.device(device).type  # never copied to the host
        for row, index in enumerate(batch["index"].tolist()):
            for k in torch.nonzero(batch["pixels"][row] >= 10).flatten().tolist():
                x0, y0, x1, y1 = batch["boxes"][row, k].tolist()
                bbox, area = written[(index + 1, k + 1)]  # COCO: 1-based image ids, [x, y, w, h]
                assert bbox == [x0, y0, x1 - x0 + 1, y1 - y0 + 1] and area == int(batch["pixels"][row, k])
                seen += 1
    assert seen >= 2 * frames


def test_generate_cli_refuses_device_with_workers_or_another_renderer(tmp_path, capsys):
    from ambulo.cli import main

    assert main(["generate", "--frames", "2", "--out", str(tmp_path / "a"), "--device", "cpu", "--workers", "2"]) != 0
    assert "drop --workers" in capsys.readouterr().err
    assert main(["generate", "--frames", "2", "--out", str(tmp_path / "b"), "--device", "cpu", "--renderer", "pbr"]) != 0
    assert "drop --renderer" in capsys.readouterr().err
    assert main(["generate", "--frames", "2", "--out", str(tmp_path / "c"), "--draw-workers", "2"]) != 0
    assert "--draw-workers 2 feeds the one-GPU batched path" in capsys.readouterr().err
    assert not any((tmp_path / d).exists() for d in "abc")  # nothing written


@pytest.mark.slow
def test_frames_split_over_two_batched_processes_make_the_one_process_dataset(tmp_path):
    # what --num-gpus does with cuda:0 and cuda:1, here with two Warp CPU devices
    one = generate(rep.example_config(96, 72), tmp_path / "one", 9, seed=5, show_progress=False,
                   device="cpu", num_worlds=2)
    two = generate(rep.example_config(96, 72), tmp_path / "two", 9, seed=5, show_progress=False,
                   device="cpu", num_worlds=2, num_gpus=2)
    a, b = json.loads(one.read_text()), json.loads(two.read_text())
    assert a["annotations"] == b["annotations"] and len(a["images"]) == 9
    for i in range(9):  # the same pixels whichever process rendered the frame
        name = f"rgb/{i:06d}.png"
        assert (tmp_path / "one" / name).read_bytes() == (tmp_path / "two" / name).read_bytes()


@pytest.mark.slow
def test_draws_in_other_processes_make_the_same_dataset(tmp_path, monkeypatch):
    # ambulo generate --device ... --draw-workers 2: the randomizers sampled a batch ahead elsewhere
    from ambulo.replicator.draw_pool import DrawPool

    submitted, submit = [], DrawPool.submit
    monkeypatch.setattr(DrawPool, "submit", lambda pool, seed, idx: submitted.append(list(idx)) or submit(pool, seed, idx))
    one = generate(rep.example_config(96, 72), tmp_path / "one", 5, seed=4, show_progress=False,
                   device="cpu", num_worlds=2)
    pool = generate(rep.example_config(96, 72), tmp_path / "pool", 5, seed=4, show_progress=False,
                    device="cpu", num_worlds=2, draw_workers=2)
    assert sorted(i for part in submitted for i in part) == list(range(5))  # every frame drawn by the pool
    assert json.loads(one.read_text())["annotations"] == json.loads(pool.read_text())["annotations"]
    for i in range(5):
        name = f"rgb/{i:06d}.png"
        assert (tmp_path / "one" / name).read_bytes() == (tmp_path / "pool" / name).read_bytes()
