"""The height-above-floor channel (``inputs="rgbdh"``): the same heights from any camera height and pitch,
read from a generated dataset's depth and frame records, left alone by the augmentations' zoom and turn,
fed by ``Detector``, ONNX and the ROS 2 bridge's camera path."""

import dataclasses
import functools

import numpy as np
import pytest
import torch

from ambulo.detection import Detector, ModelCfg, build_model, check_onnx, export_onnx, no_augment
from ambulo.detection.augment import batch_images, geometric, rotate_view, view_rotation
from ambulo.detection.dataset import CocoFrames, load_coco
from ambulo.detection.frames import FrameRecords, pad_collate
from ambulo.detection.model import HEIGHT_MAX_M, depth_channel, height_channel
from ambulo.sensors.floor_height import height_above_floor_m

W, H, FOCAL = 64, 48, 40.0
K = np.array([[FOCAL, 0.0, (W - 1) / 2], [0.0, FOCAL, (H - 1) / 2], [0.0, 0.0, 1.0]])


def camera(height_m: float, pitch_deg: float) -> np.ndarray:
    """(4, 4) world -> OpenCV camera of a camera at (0, 0, height_m) looking along +x, pitched down."""
    p = np.radians(pitch_deg)
    right, forward = np.array([0.0, -1.0, 0.0]), np.array([np.cos(p), 0.0, -np.sin(p)])
    down = np.cross(forward, right)
    r_wc = np.stack([right, down, forward], axis=1)
    t_cw = np.eye(4)
    t_cw[:3, :3] = r_wc.T
    t_cw[:3, 3] = -r_wc.T @ np.array([0.0, 0.0, height_m])
    return t_cw


def floor_depth(t_cw: np.ndarray) -> np.ndarray:
    """(H, W) depth (z, m) of the floor plane z = 0 at each pixel; 0 where the ray misses it (above the horizon)."""
    r_wc, pos = t_cw[:3, :3].T, -t_cw[:3, :3].T @ t_cw[:3, 3]
    v, u = np.mgrid[0:H, 0:W]
    rays_c = np.stack([(u - K[0, 2]) / FOCAL, (v - K[1, 2]) / FOCAL, np.ones((H, W))], -1)  # z = 1
    down_w = rays_c @ r_wc.T  # world direction per unit depth
    depth = -pos[2] / down_w[..., 2]
    return np.where(down_w[..., 2] < -1e-9, depth, 0.0)


@pytest.mark.parametrize("height_m, pitch_deg", [(1.2, 20.0), (1.6, 20.0), (1.5, 35.0)])
def test_height_above_floor_is_the_same_from_any_camera_height_and_pitch(height_m, pitch_deg):
    t_cw = camera(height_m, pitch_deg)
    depth = floor_depth(t_cw)
    point_w = np.array([2.0, 0.2, 0.4])  # 0.4 m above the floor
    p_c = t_cw[:3, :3] @ point_w + t_cw[:3, 3]
    u, v = (K @ (p_c / p_c[2]))[:2]
    depth[round(v), round(u)] = 0.0  # the nearest pixel sees a point 0.4 m high along its own ray:
    ray = np.linalg.inv(K) @ np.array([round(u), round(v), 1.0])
    r_wc, pos = t_cw[:3, :3].T, -t_cw[:3, :3].T @ t_cw[:3, 3]
    depth[round(v), round(u)] = (0.4 - pos[2]) / (r_wc @ ray)[2]  # depth where that ray is 0.4 m high
    got = height_above_floor_m(depth, K, t_cw)
    floor = (depth > 0) & ~((np.arange(H)[:, None] == round(v)) & (np.arange(W)[None] == round(u)))
    assert floor.sum() > 0.4 * H * W and np.abs(got[floor]).max() < 1e-6
    assert got[round(v), round(u)] == pytest.approx(0.4, abs=1e-6)
    assert np.all(got[depth == 0] == 0)  # no return: 0


def test_a_generated_datasets_height_channel_reads_the_floor_at_zero_and_objects_above(tiny_dataset):
    coco = load_coco(tiny_dataset)
    ids = [im["id"] for im in coco["images"]][:4]
    frames = CocoFrames(tiny_dataset, coco, ids, (128, 160), masks=True, height=True)
    records = FrameRecords(tiny_dataset, coco, ids, {c["id"]: k for k, c in enumerate(coco["categories"])},
                           height=True)
    for index in range(len(ids)):
        image, target = frames[index]
        assert image.shape == (5, 128, 160)
        height_m = image[4, :120] * HEIGHT_MAX_M
        objects = target["masks"].any(0)[:120]
        lower = torch.zeros_like(objects)
        lower[60:] = True  # the lower half of the head camera's frame is mostly floor
        assert (height_m[lower & ~objects] < 0.02).float().mean() > 0.6
        if objects.any():  # the classes stand 0.1-0.5 m high: their pixels' median is off the floor, under 0.6 m
            assert 0.03 < height_m[objects].median() < 0.6
        record = records[index]
        assert record["depth"].shape == record["height"].shape == (120, 160)
        assert torch.allclose(height_channel(record["height"].float() / 1000.0), image[4, :120], atol=1e-3)
    # a training batch's input: colour, depth, height
    batch = batch_images(pad_collate([records[i] for i in range(len(ids))]))
    assert batch.shape == (len(ids), 5, 120, 160)
    assert torch.allclose(batch[:, 4], torch.stack([frames[i][0][4, :120] for i in range(len(ids))]), atol=1e-3)


def test_zoom_and_turn_leave_heights_as_they_are():
    images = torch.zeros(1, 5, 20, 30)
    images[:, :, 4:10, 2:8] = 0.5  # an object: colour, depth 4 m, height 1 m
    instances = torch.zeros(1, 20, 30, dtype=torch.uint8)
    instances[0, 4:10, 2:8] = 1
    boxes, classes = torch.tensor([[[2.0, 4.0, 8.0, 10.0]]]), torch.tensor([[1]])
    g = torch.Generator().manual_seed(0)
    cfg = dataclasses.replace(no_augment(), scale_range=(0.5, 0.5))
    out, inst, _, _ = geometric(images, instances, boxes, classes, cfg, g)
    on = inst[0] == 1
    assert on.any() and torch.allclose(out[0, 3][on], torch.tensor(1.0))  # depth: twice as far at half the size
    assert torch.allclose(out[0, 4][on], torch.tensor(0.5))  # height: the same
    turn = view_rotation(torch.tensor([0.1]), torch.tensor([0.05]))
    out, inst, _, _ = rotate_view(images, instances, boxes, classes, turn, 25.0)
    on = inst[0] == 1
    assert on.any() and torch.allclose(out[0, 4][on], torch.tensor(0.5))
    assert not torch.allclose(out[0, 3][on], torch.tensor(0.5))  # the depth is the turned camera's


def test_an_rgbdh_detector_needs_heights_and_onnx_agrees(tiny_dataset, tmp_path):
    # an untrained 5-channel model (boxes only: a quicker export) in a checkpoint as train writes one
    model_cfg = ModelCfg(num_classes=4, inputs="rgbdh", mask_prototypes=0)
    torch.manual_seed(0)
    checkpoint = tmp_path / "checkpoint.pt"
    torch.save({"model": build_model(model_cfg).state_dict(), "model_cfg": dataclasses.asdict(model_cfg),
                "categories": ["ball", "box", "can", "cone"], "category_ids": [1, 2, 3, 4], "canvas_hw": [128, 160]},
               checkpoint)
    onnx_path = export_onnx(checkpoint, tmp_path / "rgbdh.onnx")
    coco = load_coco(tiny_dataset)
    image, _ = CocoFrames(tiny_dataset, coco, [1], (128, 160), height=True)[0]
    diff = check_onnx(checkpoint, onnx_path, image[None].numpy())
    assert diff["boxes_px"] < 1e-3 and diff["scores"] < 1e-5, diff
    rgb = (image[:3, :120].permute(1, 2, 0).numpy() * 255).round().astype(np.uint8)
    depth_m, height_m = image[3, :120].numpy() * 8.0, image[4, :120].numpy() * HEIGHT_MAX_M
    for detector in (Detector(onnx_path, score_threshold=0.0), Detector(checkpoint, score_threshold=0.0)):
        assert detector.needs_depth and detector.needs_height
        with pytest.raises(ValueError, match="height above the floor"):
            detector(rgb, depth_m)
        found = detector(rgb, depth_m, height_m)
        other = detector(rgb, depth_m, height_m + 0.5)  # the height channel reaches the network
        assert len(found.scores) and not np.allclose(found.scores[:5], other.scores[:5])
    assert float(depth_channel(torch.tensor(8.0))) == 1.0  # the decoding above: depth = channel x 8 m


def test_the_bridges_camera_path_gives_an_rgbdh_detector_heights_from_the_cameras_pose():
    from types import SimpleNamespace

    from ambulo.detection import Detections
    from ambulo.ros2.bridge_detection import DetectionWorker
    from ambulo.ros2.bridge_publishing import PhysicsPublisher

    t_cw = camera(1.3, 25.0)
    depth = floor_depth(t_cw)[..., None].astype(np.float32)
    rgb = np.zeros((H, W, 3), np.uint8)
    cam = SimpleNamespace(capture=lambda env, annotators: {"rgb": rgb, "depth": depth, "camera": {
        "width": W, "height": H, "intrinsics": K, "extrinsics_cw": t_cw}})
    calls = []

    def detector(frame, depth_m=None, height_m=None):
        calls.append((depth_m, height_m))
        return Detections(np.zeros((0, 4), np.float32), [], np.zeros(0, np.int64), np.zeros(0, np.float32))

    detector.needs_depth, detector.needs_height = True, True
    fake = SimpleNamespace(cfg=SimpleNamespace(publish_depth=False), scene=SimpleNamespace(sensor_frame={
        id(cam): "cam"}), detector=detector, _publish_frame=lambda *a: None, _publish=lambda *a: None,
        _serialize=lambda msg: b"")
    fake.detection = DetectionWorker(functools.partial(PhysicsPublisher._detect_and_publish, fake), 1,
                                     threaded=False)  # inline: the detector runs before _publish_camera returns
    PhysicsPublisher._publish_camera(fake, 0, cam, 0.5, 500_000_000)
    (depth_m, height_m), = calls
    assert depth_m is depth and height_m.shape == (H, W)
    floor = depth[..., 0] > 0
    assert floor.sum() > 0.4 * H * W and np.abs(height_m[floor]).max() < 1e-4
