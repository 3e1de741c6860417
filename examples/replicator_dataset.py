"""Tutorial: generate a labelled dataset of the warehouse scene and look at it with pycocotools.

    python examples/replicator_dataset.py --frames 20 --out /tmp/ambulo_dataset

Writes the dataset (COCO annotations.json, rgb/depth/mask PNGs) and
``boxes.png``: frame 0 with every annotated object's box, class and mask outline,
drawn from what pycocotools reads back, so the picture checks the file.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw
from pycocotools import mask as mask_utils
from pycocotools.coco import COCO

from ambulo import replicator as rep

PALETTE = [(230, 25, 75), (60, 180, 75), (255, 225, 25), (0, 130, 200), (245, 130, 48), (145, 30, 180)]


def draw_boxes(dataset: Path, image_index: int = 0) -> Path:
    coco = COCO(str(dataset / "annotations.json"))
    image_id = sorted(coco.getImgIds())[image_index]
    info = coco.loadImgs(image_id)[0]
    image = Image.open(dataset / info["file_name"]).convert("RGB")
    canvas = ImageDraw.Draw(image)
    for ann in coco.loadAnns(coco.getAnnIds(imgIds=image_id)):
        color = PALETTE[(ann["category_id"] - 1) % len(PALETTE)]
        mask = mask_utils.decode(ann["segmentation"]).astype(bool)
        edge = mask & ~(np.roll(mask, 1, 0) & np.roll(mask, -1, 0) & np.roll(mask, 1, 1) & np.roll(mask, -1, 1))
        ys, xs = np.nonzero(edge)
        for x, y in zip(xs.tolist(), ys.tolist()):
            canvas.point((x, y), fill=color)
        x, y, w, h = ann["bbox"]
        canvas.rectangle([x, y, x + w - 1, y + h - 1], outline=color, width=1)
        canvas.text((x + 2, max(0, y - 11)), coco.loadCats(ann["category_id"])[0]["name"], fill=color)
    out = dataset / "boxes.png"
    image.save(out)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--out", type=Path, default=Path("ambulo_dataset"))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    args = parser.parse_args()
    config = rep.example_config(args.width, args.height)
    rep.generate(config, args.out, num_frames=args.frames, seed=args.seed)
    print(f"boxes drawn on frame 0: {draw_boxes(args.out)}")


if __name__ == "__main__":
    main()
