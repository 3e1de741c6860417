"""What a higher camera does to the detector's depth and height-above-floor inputs (no training): frames of the
example config and of split (b)'s camera-height factor alone (0.25-0.45 m higher), the same scene otherwise; for
each, the object pixels' median depth and height, and the floor's depth and height by image row band.

A depth channel learnt at one camera height reads another world at the next; the height channel
(``--inputs rgbdh``) should read the same.

    python benchmarks/detect_height_invariance.py --frames 60 --width 160 --height 120 --out /tmp/hinv

RESULT: {split: {"object_depth_m", "object_height_m", "floor_depth_m_by_band", "floor_height_m_by_band"}}.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import detect_domain_gap as gap

from ambulo import replicator as rep

BANDS = 4
"""Row bands of the frame's lower half (where the floor is) the floor figures are given for, top to bottom."""


def inputs_of(root: Path) -> dict:
    """Medians over ``root``'s frames: object pixels' depth and height, floor pixels' by row band."""
    from ambulo.detection.dataset import instance_masks, load_coco, read_depth_mm, read_height_m
    from ambulo.detection.frames import frames_and_annotations

    coco = load_coco(root)
    images, annotations = frames_and_annotations(coco, [im["id"] for im in coco["images"]])
    object_depth, object_height = [], []
    floor_depth, floor_height = [[] for _ in range(BANDS)], [[] for _ in range(BANDS)]
    for info, anns in zip(images, annotations):
        mm = read_depth_mm(root, info)
        depth, height = mm / 1000.0, read_height_m(root, info, mm)
        h = depth.shape[0]
        objects = instance_masks(anns, h, depth.shape[1]).numpy().any(0) if anns else np.zeros(depth.shape, bool)
        object_depth.append(depth[objects])
        object_height.append(height[objects])
        floor = ~objects & (depth > 0) & (height < 0.02)  # the floor: what stands under 2 cm
        for b, rows in enumerate(np.array_split(np.arange(h // 2, h), BANDS)):
            floor_depth[b].append(depth[rows][floor[rows]])
            floor_height[b].append(height[rows][~objects[rows] & (depth[rows] > 0)])

    def median(parts):
        return round(float(np.median(np.concatenate(parts))), 3)

    return {"object_depth_m": median(object_depth), "object_height_m": median(object_height),
            "floor_depth_m_by_band": [median(p) for p in floor_depth],
            "floor_height_m_by_band": [median(p) for p in floor_height]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--width", type=int, default=160)
    parser.add_argument("--height", type=int, default=120)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", default="runs/height_invariance")
    args = parser.parse_args()
    out = Path(args.out)
    # seed 1: split (b)'s and its factors' seed, for both (the same draws but the camera's height)
    splits = {"example_config": gap.make(rep.example_config(args.width, args.height), out / "example", args.frames, 1,
                                         args.workers),
              "unseen_camera_height_only": gap.make(gap.config(args.width, args.height, ("camera_height",)),
                                                    out / "camera_height", args.frames, 1, args.workers)}
    result = {name: inputs_of(folder) for name, folder in splits.items()}
    for name, r in result.items():
        print(f"{name:>26}: {r}")
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
