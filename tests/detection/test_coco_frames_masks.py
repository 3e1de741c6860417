"""``CocoFrames(masks=True)``: each target carries its objects' masks on the canvas, as the COCO
segmentation gives them, the padding empty; without ``masks`` the target has none."""

import numpy as np
import torch
from pycocotools import mask as mask_utils

from ambulo.detection.dataset import CocoFrames, load_coco

FRAME_PX = 48
CANVAS_HW = (64, 96)


def test_masks_are_each_objects_segmentation_on_the_padded_canvas(tmp_path, shapes_dataset):
    root = shapes_dataset(tmp_path, num_frames=1, size_px=FRAME_PX)
    coco = load_coco(root)
    image, target = CocoFrames(root, coco, [1], CANVAS_HW, masks=True)[0]
    masks = target["masks"]
    assert image.shape == (3, *CANVAS_HW)
    assert masks.dtype == torch.bool and masks.shape == (2, *CANVAS_HW)
    by_category = {a["category_id"]: a for a in coco["annotations"] if a["image_id"] == 1}
    for mask, category in zip(masks, target["labels"].tolist()):
        seg = by_category[category]["segmentation"]
        truth = mask_utils.decode({"size": seg["size"], "counts": seg["counts"].encode()}).astype(bool)
        np.testing.assert_array_equal(mask[:FRAME_PX, :FRAME_PX].numpy(), truth)
        assert truth.sum() > 100  # a disc or a square of radius 7-11 px, not an empty mask
    assert not masks[:, FRAME_PX:].any() and not masks[:, :, FRAME_PX:].any()
    assert "masks" not in CocoFrames(root, coco, [1], CANVAS_HW)[0][1]
