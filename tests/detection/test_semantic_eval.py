"""The semantic evaluation's ground truth is the dataset's own semantic image: the COCO annotations'
masks painted with their category ids equal ``replicator.manifest.semantic_image`` (the instance PNG
looked up in ``dataset.json``'s ``instance_categories``) on every frame of a generated dataset, except
the objects too small to be annotated (``WriterCfg.min_visible_pixels``), which are background in both
the COCO and the semantic ground truth."""

import imageio.v3 as iio
import numpy as np

from ambulo.detection import load_coco
from ambulo.detection.semantic import ground_truth_semantic
from ambulo.replicator.manifest import semantic_image as dataset_semantic_image
from ambulo.replicator.writers import WriterCfg, frame_stem


def test_ground_truth_is_the_datasets_semantic_image(tiny_dataset):
    coco = load_coco(tiny_dataset)
    by_image: dict[int, list[dict]] = {im["id"]: [] for im in coco["images"]}
    for ann in coco["annotations"]:
        by_image[ann["image_id"]].append(ann)
    objects = 0
    for image in coco["images"]:
        painted = ground_truth_semantic(by_image[image["id"]], (image["height"], image["width"]))
        expected = dataset_semantic_image(tiny_dataset, image["frame"])
        instances = iio.imread(tiny_dataset / "instance" / f"{frame_stem(image['frame'])}.png")
        ids, counts = np.unique(instances, return_counts=True)
        too_small = ids[(ids > 0) & (counts < WriterCfg().min_visible_pixels)]
        unannotated = np.isin(instances, too_small)
        np.testing.assert_array_equal(painted[~unannotated], expected[~unannotated], err_msg=f"frame {image['frame']}")
        assert (painted[unannotated] == 0).all()
        objects += int((expected[~unannotated] > 0).sum())
    assert objects > 0, "no object pixels in the dataset: the comparison would be of empty images"
