"""Batch augmentations on the device: boxes and instance maps move exactly with the pixels, erased
objects are dropped, the photometric changes stay in range and are the identity when off; the padded
loss ignores padding; resident and streamed frames are the same records."""

import dataclasses

import pytest
import torch

from ambulo.detection import AugmentCfg, load_coco, no_augment
from ambulo.detection.augment import erase, geometric, photometric
from ambulo.detection.frames import FrameRecords, ResidentFrames, pad_collate, pad_rows
from ambulo.detection.loss import centernet_loss, mask_cells


def block_batch():
    """One 20 x 30 frame with a white object at x 2..8, y 4..10 (instance 1) and a padded box slot."""
    images = torch.zeros(1, 3, 20, 30)
    images[:, :, 4:10, 2:8] = 1.0
    instances = torch.zeros(1, 20, 30, dtype=torch.uint8)
    instances[0, 4:10, 2:8] = 1
    boxes = torch.tensor([[[2.0, 4.0, 8.0, 10.0], [0.0, 0.0, 0.0, 0.0]]])
    return images, instances, boxes, torch.tensor([[3, -1]])


def geometry(flip: float, scale: float) -> AugmentCfg:
    return dataclasses.replace(no_augment(), flip_probability=flip, scale_range=(scale, scale))


def test_flip_and_scale_move_boxes_and_masks_with_the_pixels():
    images, instances, boxes, classes = block_batch()
    g = torch.Generator().manual_seed(0)
    out, inst, out_boxes, out_classes = geometric(images, instances, boxes, classes, geometry(1.0, 1.0), g)
    assert torch.equal(out_boxes[0, 0], torch.tensor([22.0, 4.0, 28.0, 10.0]))
    assert out[0, 0, 4:10, 22:28].min() == 1 and out[0, 0].sum() == 36 and torch.equal(inst[0] == 1, out[0, 0] > 0.5)
    assert out_classes.tolist() == [[3, -1]]  # the padded slot stays padding
    # a central object: no window of a 1.5x zoom cuts it
    images, instances = images.roll((3, 10), dims=(-2, -1)), instances.roll((3, 10), dims=(-2, -1))
    boxes = boxes + torch.tensor([10.0, 3.0, 10.0, 3.0]) * (classes >= 0)[..., None]
    for scale in (0.5, 1.5):
        out, inst, out_boxes, out_classes = geometric(images, instances, boxes, classes, geometry(0.0, scale), g)
        x0, y0, x1, y1 = out_boxes[0, 0].tolist()
        ys, xs = torch.nonzero(inst[0] == 1, as_tuple=True)
        assert out_classes[0, 0] == 3 and (x1 - x0, y1 - y0) == pytest.approx((6 * scale, 6 * scale), abs=1e-4)
        # the mask's pixels fill the box (to the nearest pixel) and the image's bright pixels are the mask's
        assert abs(xs.min().item() - x0) <= 1 and abs(xs.max().item() + 1 - x1) <= 1
        assert abs(ys.min().item() - y0) <= 1 and abs(ys.max().item() + 1 - y1) <= 1
        bright, mask = out[0, 0] > 0.5, inst[0] == 1  # bilinear pixels and nearest ids differ at the edge only
        assert (bright & mask).sum() >= 0.6 * (bright | mask).sum()
    # an object cut away by the crop is dropped: it sat in the corner a 3x zoom leaves out
    corner = torch.tensor([[[27.0, 0.0, 30.0, 3.0]]])
    kept = [geometric(images, instances, corner, torch.tensor([[1]]), geometry(0.0, 3.0), g)[3].item()
            for _ in range(20)]
    assert -1 in kept and 1 in kept  # cut away by most windows, kept by those that hold the corner


def test_erasing_drops_the_objects_it_hides():
    images, instances, boxes, classes = block_batch()
    images, instances = images.repeat(64, 1, 1, 1), instances.repeat(64, 1, 1)
    classes = classes.repeat(64, 1)
    cfg = dataclasses.replace(no_augment(), erase_probability=1.0, erase_count=1, erase_size_range=(0.4, 0.6))
    out, inst, out_classes = erase(images, instances, classes, cfg, torch.Generator().manual_seed(0))
    visible = (inst == 1).flatten(1).sum(1).float() / 36
    assert torch.equal(out_classes[:, 0] == 3, visible >= cfg.min_visible_fraction)
    assert (out_classes[:, 0] == -1).any() and (out_classes[:, 0] == 3).any() and (out_classes[:, 1] == -1).all()
    painted = (out != images).any(dim=1)
    assert painted.any() and not (painted & (inst > 0)).any()  # erased pixels left the instance map


def test_occluders_are_ellipses_or_rectangles_shaded_across():
    blank = torch.zeros(64, 3, 40, 40), torch.zeros(64, 40, 40, dtype=torch.uint8)
    classes = torch.full((64, 1), -1)
    base = dataclasses.replace(no_augment(), erase_probability=1.0, erase_count=1, erase_size_range=(0.5, 0.9))
    fill = {}
    for ellipse in (0.0, 1.0):
        cfg = dataclasses.replace(base, erase_ellipse_probability=ellipse, erase_shading=0.4)
        out, _, _ = erase(*blank, classes, cfg, torch.Generator().manual_seed(0))
        painted = (out > 0).any(dim=1)
        whole = [i for i in range(64) if painted[i].any() and not (painted[i, 0].any() or painted[i, -1].any()
                                                                    or painted[i, :, 0].any() or painted[i, :, -1].any())]
        # the share of its bounding box a shape fills: 1 for a rectangle, pi / 4 for an ellipse
        shares = [painted[i].sum().item() / ((painted[i].any(1).sum() * painted[i].any(0).sum()).item())
                  for i in whole]
        fill[ellipse] = sum(shares) / len(shares)
        # shaded: a shape's pixels are not one colour (its brightness changes across it)
        spread = torch.tensor([out[i][:, painted[i]].std(dim=1).max().item() for i in whole])
        assert spread.median() > 0.01
    assert fill[0.0] > 0.97 and abs(fill[1.0] - torch.pi / 4) < 0.06, fill


def test_uneven_light_is_a_gain_ramp_within_its_range():
    flat = torch.full((32, 3, 30, 40), 0.25)
    cfg = dataclasses.replace(no_augment(), light_gradient=0.5)
    out = photometric(flat, cfg, torch.Generator().manual_seed(0))
    corners = torch.stack([out[:, 0, 0, 0], out[:, 0, 0, -1], out[:, 0, -1, 0], out[:, 0, -1, -1]], dim=1)
    log_ratio = (corners.amax(1) / corners.amin(1)).log()
    assert log_ratio.max() <= 2 * 0.5 + 1e-4 and log_ratio.max() > 0.5  # corners differ, at most e ** 1
    # a ramp: the gain's log is a plane, so opposite corners' logs average to the centre's
    centre = out[:, 0, 14:16, 19:21].mean(dim=(1, 2)).log()
    assert torch.allclose((corners[:, 0].log() + corners[:, 3].log()) / 2, centre, atol=0.05)


def test_photometric_is_the_identity_when_off_and_stays_in_range():
    images = torch.rand(8, 3, 12, 16, generator=torch.Generator().manual_seed(0))
    same = photometric(images, no_augment(), torch.Generator().manual_seed(1))
    assert torch.allclose(same, images, atol=1e-5)
    changed = photometric(images, AugmentCfg(), torch.Generator().manual_seed(1))
    assert changed.min() >= 0 and changed.max() <= 1
    # each image its own draw: the per-image mean brightness ratios differ
    ratios = changed.mean(dim=(1, 2, 3)) / images.mean(dim=(1, 2, 3))
    assert ratios.std() > 0.05
    grey = photometric(images, dataclasses.replace(no_augment(), grey_probability=1.0), torch.Generator())
    assert torch.allclose(grey[:, 0], grey[:, 1], atol=1e-5) and torch.allclose(grey[:, 1], grey[:, 2], atol=1e-5)


def test_the_loss_ignores_padding_and_sums_over_images():
    torch.manual_seed(0)
    maps = {"heat": torch.randn(2, 3, 8, 10), "size": torch.rand(2, 2, 8, 10) * 4, "offset": torch.rand(2, 2, 8, 10),
            "proto": torch.randn(2, 4, 8, 10), "coef": torch.randn(2, 4, 8, 10)}
    boxes = [torch.tensor([[4.0, 4.0, 20.0, 14.0], [22.0, 10.0, 34.0, 30.0]]), torch.tensor([[1.0, 2.0, 9.0, 12.0]])]
    classes = [torch.tensor([0, 2]), torch.tensor([1])]
    instances = torch.zeros(2, 32, 40, dtype=torch.uint8)
    instances[0, 4:14, 4:20], instances[0, 10:30, 22:34], instances[1, 2:12, 1:9] = 1, 2, 1

    def loss(width: int) -> dict:
        return centernet_loss(maps, pad_rows(boxes, 0.0, width), pad_rows(classes, -1, width),
                              mask_cells(instances, width))

    narrow, wide = loss(2), loss(5)
    assert all(torch.allclose(narrow[k], wide[k]) for k in narrow)
    # the batch's loss is its images' losses weighted by their box counts (normalised by all boxes)
    single = [centernet_loss({k: v[i:i + 1] for k, v in maps.items()}, boxes[i][None], classes[i][None],
                             mask_cells(instances[i:i + 1], len(boxes[i]))) for i in range(2)]
    assert torch.allclose(narrow["total"], (2 * single[0]["total"] + single[1]["total"]) / 3)


def test_resident_frames_are_the_streamed_records(tiny_dataset):
    coco = load_coco(tiny_dataset)
    ids = [im["id"] for im in coco["images"]]
    records = FrameRecords(tiny_dataset, coco, ids, {c["id"]: k for k, c in enumerate(coco["categories"])})
    resident = ResidentFrames(records, torch.device("cpu"), chunk=3)
    index = torch.tensor([5, 0, 7])
    got = resident.batch(index)
    want = pad_collate([records[i] for i in index.tolist()])
    m = want["boxes"].shape[1]
    assert torch.equal(got["images"], want["images"]) and torch.equal(got["instances"], want["instances"])
    assert torch.equal(got["boxes"][:, :m], want["boxes"]) and torch.equal(got["classes"][:, :m], want["classes"])
    assert (got["classes"][:, m:] == -1).all()
    # every annotation is an instance of the map, with its box around it
    record = records[0]
    for k, box in enumerate(record["boxes"]):
        ys, xs = torch.nonzero(record["instances"] == k + 1, as_tuple=True)
        if len(xs):
            assert xs.min() >= box[0] - 1 and xs.max() + 1 <= box[2] + 1 and ys.min() >= box[1] - 1


def test_view_rotation_moves_points_depths_and_boxes_as_a_turned_pinhole_camera_sees_them():
    """A blob at the projection of a 3D point P (old camera frame) lands where the turned camera projects R P,
    its depth becomes (R P)_z, and its box holds its warped mask; no turn is the identity."""
    from ambulo.detection.augment import rotate_view, view_rotation
    from ambulo.detection.model import depth_channel

    h, w, focal = 48, 64, 40.0
    point = torch.tensor([0.6, -0.5, 2.0])  # m, x right, y down, z forward
    u, v = focal * point[0] / point[2] + w / 2, focal * point[1] / point[2] + h / 2  # (44, 14) px
    images = torch.zeros(1, 4, h, w)
    instances = torch.zeros(1, h, w, dtype=torch.uint8)
    rows, cols = slice(int(v) - 2, int(v) + 2), slice(int(u) - 2, int(u) + 2)  # a 4 x 4 px blob centred on (u, v)
    images[0, :3, rows, cols], images[0, 3, rows, cols], instances[0, rows, cols] = 1.0, depth_channel(point[2]), 1
    boxes, classes = torch.tensor([[[u - 2, v - 2, u + 2, v + 2]]]), torch.tensor([[2]])
    same = rotate_view(images, instances, boxes, classes, torch.eye(3)[None], focal)
    assert torch.allclose(same[0], images, atol=1e-5) and torch.equal(same[1], instances)
    assert torch.allclose(same[2], boxes, atol=1e-4) and same[3].tolist() == [[2]]
    for pitch_deg, roll_deg in ((10.0, 0.0), (-8.0, 5.0)):
        rotation = view_rotation(torch.deg2rad(torch.tensor([pitch_deg])), torch.deg2rad(torch.tensor([roll_deg])))
        assert torch.allclose(rotation[0] @ rotation[0].T, torch.eye(3), atol=1e-6)
        out, inst, out_boxes, out_classes = rotate_view(images, instances, boxes, classes, rotation, focal)
        turned = rotation[0] @ point
        u1, v1 = focal * turned[0] / turned[2] + w / 2, focal * turned[1] / turned[2] + h / 2
        ys, xs = torch.nonzero(inst[0] == 1, as_tuple=True)
        assert (xs.float() + 0.5).mean().item() == pytest.approx(u1.item(), abs=0.6)
        assert (ys.float() + 0.5).mean().item() == pytest.approx(v1.item(), abs=0.6)
        assert (v1 < v) == (pitch_deg > 0)  # turned down: the scene moves up the frame
        assert out[0, 3][inst[0] == 1].mean().item() == pytest.approx(depth_channel(turned[2]).item(), rel=0.005)
        assert abs(turned[2] / point[2] - 1) > 0.02  # 6 % and 2.5 % nearer / farther: the check can say no
        x0, y0, x1, y1 = out_boxes[0, 0].tolist()
        assert out_classes.tolist() == [[2]] and x0 <= xs.min() + 0.5 and xs.max() + 0.5 <= x1
        assert y0 <= ys.min() + 0.5 and ys.max() + 0.5 <= y1 and (x1 - x0) * (y1 - y0) < 1.6 * 16


def test_viewpoint_augmentation_is_off_by_default_and_on_in_its_preset():
    from ambulo.detection import AugmentCfg, augment_batch, viewpoint

    images, instances, boxes, classes = block_batch()
    batch = {"images": (images[:, :3] * 255).to(torch.uint8), "instances": instances, "boxes": boxes,
             "classes": classes}
    off = dataclasses.replace(no_augment(), view_pitch_deg=0.0)
    on = dataclasses.replace(no_augment(), view_pitch_deg=15.0, view_roll_deg=5.0)
    assert AugmentCfg().view_pitch_deg == 0 and viewpoint().view_pitch_deg > 0 and viewpoint().view_roll_deg > 0
    same = augment_batch(batch, off, torch.Generator().manual_seed(0))
    assert torch.equal(same["boxes"], boxes)
    moved = augment_batch(batch, on, torch.Generator().manual_seed(0))
    assert not torch.allclose(moved["boxes"][0, 0], boxes[0, 0])
