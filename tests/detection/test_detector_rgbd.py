"""RGB-D detectors (``ModelCfg.inputs="rgbd"``): the 4-channel model's shapes, depth read aligned with
the colour and warped with it by the augmentations (nearer by a zoom), ONNX Runtime agreeing with torch,
and a tiny training that learns what only depth tells: two squares of one look at two depths."""

import dataclasses
import functools
import json

import imageio.v3 as iio
import numpy as np
import pytest
import torch

from ambulo.detection import Detector, ModelCfg, TrainCfg, build_model, check_onnx, export_onnx, no_augment, train
from ambulo.detection.augment import batch_images, geometric
from ambulo.detection.dataset import CocoFrames, load_coco
from ambulo.detection.frames import FrameRecords, pad_collate
from ambulo.detection.model import DEPTH_MAX_M, depth_channel
from ambulo.detection.transfer import evaluate_checkpoint

NEAR_M, FAR_M, FLOOR_M = 1.0, 3.0, 5.0


def write_depth_twins(root, num_frames: int = 4, size_px: int = 64, seed: int = 0):
    """A COCO dataset with depth PNGs (mm): each frame one 'near' (1 m) and one 'far' (3 m) grey square
    of the same size and colour on a floor 5 m away, one in each half of the frame (which one where: a
    coin), so only the depth tells their classes apart."""
    rng = np.random.default_rng(seed)
    (root / "rgb").mkdir(parents=True, exist_ok=True)
    (root / "depth").mkdir(parents=True, exist_ok=True)
    images, annotations = [], []
    side = 16
    for index in range(num_frames):
        rgb = np.full((size_px, size_px, 3), 60, np.uint8)
        depth_mm = np.full((size_px, size_px), int(FLOOR_M * 1000), np.uint16)
        near_left = rng.random() < 0.5
        for category_id, depth_m in ((1, NEAR_M), (2, FAR_M)):
            x_lo = 8 if (category_id == 1) == near_left else size_px // 2 + 8
            x0, y0 = x_lo + int(rng.integers(0, 4)), 24 + int(rng.integers(0, 4))
            rgb[y0:y0 + side, x0:x0 + side] = 200
            depth_mm[y0:y0 + side, x0:x0 + side] = int(depth_m * 1000)
            annotations.append({"id": len(annotations) + 1, "image_id": index + 1, "category_id": category_id,
                                "bbox": [x0, y0, side, side], "area": side * side, "iscrowd": 0})
        name = f"{index:06d}.png"
        iio.imwrite(root / "rgb" / name, rgb)
        iio.imwrite(root / "depth" / name, depth_mm)
        images.append({"id": index + 1, "file_name": f"rgb/{name}", "width": size_px, "height": size_px})
    categories = [{"id": 1, "name": "near"}, {"id": 2, "name": "far"}]
    (root / "annotations.json").write_text(json.dumps({"images": images, "annotations": annotations,
                                                       "categories": categories}))
    return root


def test_rgbd_model_takes_four_channels_and_keeps_the_output_shapes():
    rgbd = build_model(ModelCfg(num_classes=2, inputs="rgbd")).eval()
    maps = rgbd(torch.rand(2, 4, 64, 96))
    assert maps["heat"].shape == (2, 2, 16, 24) and maps["size"].shape == maps["offset"].shape == (2, 2, 16, 24)
    assert maps["proto"].shape[:1] + maps["proto"].shape[2:] == (2, 16, 24)
    assert rgbd.stages[0][0].weight.shape[1] == 4
    with pytest.raises(RuntimeError):  # an rgb model is no rgbd one
        build_model(ModelCfg(num_classes=2))(torch.rand(1, 4, 64, 96))
    # the depth encoding: metres over DEPTH_MAX_M, clipped; no return (0, NaN) is 0
    got = depth_channel(torch.tensor([0.0, 2.0, DEPTH_MAX_M * 2, float("nan")]))
    assert got.tolist() == [0.0, 2.0 / DEPTH_MAX_M, 1.0, 0.0]


def ramp_dataset(root, w: int = 40, h: int = 24):
    """One frame whose depth rises 20 mm a column from 1 m (a ramp along x) and whose colour's red
    channel is the column index: every warped pixel says where it came from in both."""
    (root / "rgb").mkdir(parents=True)
    (root / "depth").mkdir(parents=True)
    xs = np.arange(w)
    rgb = np.zeros((h, w, 3), np.uint8)
    rgb[..., 0] = 5 * xs
    iio.imwrite(root / "rgb" / "000000.png", rgb)
    iio.imwrite(root / "depth" / "000000.png", np.tile((1000 + 20 * xs).astype(np.uint16), (h, 1)))
    coco = {"images": [{"id": 1, "file_name": "rgb/000000.png", "width": w, "height": h}],
            "annotations": [{"id": 1, "image_id": 1, "category_id": 1, "bbox": [10, 6, 8, 8], "area": 64,
                             "iscrowd": 0}],
            "categories": [{"id": 1, "name": "thing"}]}
    (root / "annotations.json").write_text(json.dumps(coco))
    return root, 1.0 + 0.02 * xs


def test_depth_is_read_aligned_and_warped_with_the_pixels(tmp_path):
    root, ramp_m = ramp_dataset(tmp_path)
    coco = load_coco(root)
    # evaluation frames: the 4th channel is the depth PNG's, on the same pixels, padded with 0
    image, _ = CocoFrames(root, coco, [1], (32, 64), depth=True)[0]
    assert image.shape == (4, 32, 64)
    assert torch.allclose(image[3, :24, :40], depth_channel(torch.tensor(ramp_m, dtype=torch.float32)).expand(24, 40))
    assert (image[3, 24:] == 0).all() and (image[3, :, 40:] == 0).all()
    # training records: the same depth, through the batch's encoding
    batch = pad_collate([FrameRecords(root, coco, [1], {1: 0}, depth=True)[0]])
    images = batch_images(batch)
    assert torch.allclose(images[:, 3], image[3, :24, :40])
    g = torch.Generator().manual_seed(0)
    off = dataclasses.replace(no_augment(), flip_probability=1.0)
    flipped = geometric(images, batch["instances"], batch["boxes"], batch["classes"], off, g)[0]
    assert torch.allclose(flipped[0, 3], images[0, 3].flip(-1), atol=1e-6)  # the ramp falls along x now
    assert torch.allclose(flipped[0, 0], images[0, 0].flip(-1), atol=1e-6)
    # a 2x zoom: each pixel's depth is its source pixel's (nearest: no blend) halved, the source being
    # where its colour came from (the box tells the crop's offset: x0' = 2 x0 + tx)
    zoom = dataclasses.replace(no_augment(), scale_range=(2.0, 2.0))
    out, _, boxes, _ = geometric(images, batch["instances"], batch["boxes"], batch["classes"], zoom, g)
    tx = boxes[0, 0, 0].item() - 2 * 10
    source_x = (torch.arange(40) + 0.5 - tx) / 2 - 0.5  # the continuous source column of each output column
    expected_m = (1.0 + 0.02 * source_x) / 2
    depth_m = out[0, 3] * DEPTH_MAX_M
    assert torch.allclose(depth_m, expected_m.expand(24, 40), atol=0.5 * 0.02 / 2 + 1e-4)
    # nearest: every depth is one a source pixel has (halved), none a blend of two (a depth nothing has)
    sources = images[0, 3, 0]
    assert ((out[0, 3].flatten()[:, None] * 2 - sources[None]).abs().amin(dim=1) < 1e-6).all()
    # and the colour agrees: red = 5 * source column (bilinear), so depth and colour stay aligned
    assert torch.allclose(out[0, 0] * 255, 5 * source_x.clamp(0, 39).expand(24, 40), atol=0.6)


def test_rgbd_training_learns_what_only_depth_tells_and_onnx_agrees(tmp_path):
    root = write_depth_twins(tmp_path / "twins", num_frames=8)
    fresh = write_depth_twins(tmp_path / "fresh", num_frames=8, seed=1)  # frames training never saw
    cfg = TrainCfg(epochs=40, batch_size=8, learning_rate=3e-3, warmup_steps=10, num_workers=0, eval_every_epochs=0,
                   held_out_fraction=0.0, augment=no_augment(), mask_prototypes=0, inputs="rgbd")
    rgbd = train(root, tmp_path / "rgbd", cfg, show_progress=False)
    losses = [loss for _, loss in rgbd.losses]
    assert sum(losses[-5:]) / 5 < 0.5 * sum(losses[:5]) / 5, losses
    # the same squares, told apart by depth alone: on frames it never saw, the rgbd model finds each as
    # its class (mAP50 1.0, 0.91, 1.0 with seeds 0-2); the same training of an rgb model, which can only
    # guess which square is which, scored 0.62
    by_depth = evaluate_checkpoint(tmp_path / "rgbd" / "checkpoint.pt", fresh)
    assert by_depth["mAP50"] > 0.85, by_depth
    # ONNX export of the 4-channel graph: the runtime agrees with torch on a real frame with its depth
    checkpoint = tmp_path / "rgbd" / "checkpoint.pt"
    onnx_path = export_onnx(checkpoint, tmp_path / "rgbd.onnx")
    image = CocoFrames(root, load_coco(root), [1], (64, 64), depth=True)[0][0][None].numpy()
    diff = check_onnx(checkpoint, onnx_path, image)
    assert diff["compared"] >= 10 and diff["unmatched"] <= 0.05 * diff["compared"], diff
    assert diff["boxes_px"] < 1e-3 and diff["scores"] < 1e-5, diff
    rgb_frame = iio.imread(root / "rgb" / "000000.png")
    depth_m = iio.imread(root / "depth" / "000000.png") / 1000.0
    for detector in (Detector(onnx_path), Detector(checkpoint)):
        found = detector(rgb_frame, depth_m)
        assert sorted(found.labels[:2]) == ["far", "near"], found
        with pytest.raises(ValueError, match="depth"):
            detector(rgb_frame)


def test_the_bridges_camera_path_gives_an_rgbd_detector_the_frames_depth():
    """``PhysicsPublisher._publish_camera`` with a detector that needs depth captures the camera's depth
    (even with publish_depth off) and hands it over with the very frame; an rgb detector gets none."""
    from types import SimpleNamespace

    from ambulo.detection import Detections
    from ambulo.ros2.bridge_detection import DetectionWorker
    from ambulo.ros2.bridge_publishing import PhysicsPublisher
    from ambulo.viewer.detections import ShownDetector

    rgb = np.random.default_rng(0).integers(0, 255, (6, 8, 3), dtype=np.uint8)
    depth = np.random.default_rng(1).random((6, 8, 1)).astype(np.float32)
    camera = SimpleNamespace(captured=[])

    def capture(env, annotators):
        camera.captured.append(tuple(annotators))
        return {"rgb": rgb, "depth": depth, "camera": {"width": 8, "height": 6, "intrinsics": np.eye(3)}}

    camera.capture = capture

    def publish(needs_depth: bool) -> list:
        calls = []

        def detector(frame, depth_m=None):
            calls.append((frame, depth_m))
            return Detections(np.zeros((0, 4), np.float32), [], np.zeros(0, np.int64), np.zeros(0, np.float32))

        detector.needs_depth = needs_depth
        viewer = SimpleNamespace(show_image=lambda *a: None, show_detections=lambda *a: None)
        shown = ShownDetector(detector, viewer)  # the bridge's --viewer wrapper passes depth on as well
        fake = SimpleNamespace(cfg=SimpleNamespace(publish_depth=False), scene=SimpleNamespace(sensor_frame={
            id(camera): "cam"}), detector=shown, _publish_frame=lambda *a: None, _publish=lambda *a: None,
            _serialize=lambda msg: b"")
        fake.detection = DetectionWorker(functools.partial(PhysicsPublisher._detect_and_publish, fake), 1,
                                         threaded=False)  # inline: the detector runs before _publish_camera returns
        PhysicsPublisher._publish_camera(fake, 0, camera, 0.5, 500_000_000)
        return calls

    calls = publish(needs_depth=True)
    assert camera.captured[-1] == ("rgb", "depth")
    assert len(calls) == 1 and np.array_equal(calls[0][0], rgb) and calls[0][1] is depth
    calls = publish(needs_depth=False)
    assert camera.captured[-1] == ("rgb",)
    assert len(calls) == 1 and np.array_equal(calls[0][0], rgb) and calls[0][1] is None
