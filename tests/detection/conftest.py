"""Shared set-up of the detection tests: datasets, a small trained detector, and torch's intra-op
pool at one thread in this process.

One thread: the tests train small detectors (64x64 frames, batches of 4-8) whose ops are too small
to split; with torch's default two threads on a 2-core machine that other jobs keep busy, each op
waits for a descheduled worker (as in tests/rl/conftest.py). Measured at load ~3-4: the rgbd
training test 33-55 s with 2 threads, 8-10 s with 1; the same training steps and checks. Tests that
launch ``ambulo`` in a subprocess keep that process's own default."""

import contextlib
import dataclasses

import pytest
import torch

from ambulo import replicator as rep


@contextlib.contextmanager
def one_torch_thread():
    """torch's intra-op pool at 1 thread inside, restored after."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(before)


@pytest.fixture(autouse=True, scope="package")
def _one_torch_thread():
    # package scope: set up after the session fixtures below, which pin the thread themselves
    with one_torch_thread():
        yield


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory):
    """8 frames of the example warehouse at 160x120 made by the project's own generator."""
    config = rep.example_config()
    config = dataclasses.replace(config, camera=dataclasses.replace(config.camera, width=160, height=120))
    out = tmp_path_factory.mktemp("detection_data")
    with one_torch_thread():
        rep.generate(config, out, num_frames=8, seed=3, workers=1, show_progress=False)
    return out


@pytest.fixture(scope="session")
def trained_shapes(tmp_path_factory):
    """(dataset folder, checkpoint) of a detector trained 40 steps on 4 frames of discs and squares."""
    from ambulo.detection import TrainCfg, no_augment, train

    root = write_shapes_dataset(tmp_path_factory.mktemp("shapes"), num_frames=4)
    run = tmp_path_factory.mktemp("shapes_run")
    cfg = TrainCfg(epochs=40, batch_size=4, learning_rate=5e-3, warmup_steps=0, num_workers=0, eval_every_epochs=0,
                   held_out_fraction=0.0, augment=no_augment())
    with one_torch_thread():  # a session fixture: set up before the package's one-thread fixture
        train(root, run, cfg, show_progress=False)
    return root, run / "checkpoint.pt"


@pytest.fixture
def perfect_results():
    """A function: a COCO dict's annotations as results of score 1 (boxes and masks), what a perfect
    detector would return."""
    def results(coco):
        return [{"image_id": a["image_id"], "category_id": a["category_id"], "segmentation": a["segmentation"],
                 "bbox": a["bbox"], "score": 1.0} for a in coco["annotations"]]
    return results


@pytest.fixture
def shapes_dataset():
    """``write_shapes_dataset``: a function (tests pick the folder and the number of frames)."""
    return write_shapes_dataset


def write_shapes_dataset(root, num_frames: int = 5, size_px: int = 64, seed: int = 0):
    """A COCO dataset of ``num_frames`` frames of one disc and one square each, on a grey floor,
    with their RLE masks: shapes whose masks differ from their boxes, a task a mask head must learn."""
    import json

    import imageio.v3 as iio
    import numpy as np
    from pycocotools import mask as mask_utils

    rng = np.random.default_rng(seed)
    (root / "rgb").mkdir(parents=True, exist_ok=True)
    images, annotations = [], []
    yy, xx = np.mgrid[0:size_px, 0:size_px] + 0.5
    for index in range(num_frames):
        rgb = np.full((size_px, size_px, 3), 90, np.uint8)
        half = size_px // 2
        for category_id, (x_lo, colour) in ((1, (0, (230, 60, 40))), (2, (half, (40, 90, 230)))):
            r = rng.uniform(7, 11)
            cx, cy = rng.uniform(x_lo + r + 1, x_lo + half - r - 1), rng.uniform(r + 1, size_px - r - 1)
            if category_id == 1:
                mask = (xx - cx) ** 2 + (yy - cy) ** 2 <= r ** 2
            else:
                mask = (np.abs(xx - cx) <= r) & (np.abs(yy - cy) <= r)
            rgb[mask] = colour
            rle = mask_utils.encode(np.asfortranarray(mask.astype(np.uint8)))
            annotations.append({"id": len(annotations) + 1, "image_id": index + 1, "category_id": category_id,
                                "bbox": mask_utils.toBbox(rle).tolist(), "area": int(mask.sum()), "iscrowd": 0,
                                "segmentation": {"size": [size_px, size_px], "counts": rle["counts"].decode()}})
        name = f"rgb/{index:06d}.png"
        iio.imwrite(root / name, rgb)
        images.append({"id": index + 1, "file_name": name, "width": size_px, "height": size_px})
    categories = [{"id": 1, "name": "disc"}, {"id": 2, "name": "square"}]
    (root / "annotations.json").write_text(json.dumps({"images": images, "annotations": annotations,
                                                       "categories": categories}))
    return root
