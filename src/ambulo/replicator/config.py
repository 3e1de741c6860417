"""What a dataset is made of: a scene, one camera, randomizers in order, and writers."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import mujoco

from ambulo.core import PhysicsCfg
from ambulo.sensors import CameraCfg
from ambulo.utils.validate import Checked

from .randomizers import Randomizer
from .writers import WriterCfg, default_writer_cfg

# The annotators every dataset frame needs for COCO, masks, KITTI and the record. Not
# semantic_segmentation: as Replicator's BasicWriter, a semantic image is written only when asked
# (add it to a camera's annotators); ``manifest.semantic_image`` derives it from the instance image.
DATASET_ANNOTATORS = ("rgb", "depth", "instance_segmentation",
                      "bounding_box_2d_tight", "bounding_box_2d_loose", "bounding_box_3d")


@dataclass(kw_only=True)
class DatasetConfig(Checked):
    name: str = "ambulo_dataset"
    build_scene: Callable[[], mujoco.MjSpec]
    """Returns the scene's spec (built with ``ambulo.core.scene``) with semantic labels
    (``ambulo.core.set_semantic_label``); called once per process."""
    physics: PhysicsCfg = field(default_factory=PhysicsCfg)
    """Physics of the scene (poses are set, not simulated, but the model compiles with it)."""
    camera: CameraCfg
    """The camera that takes the dataset's pictures."""
    randomizers: list[Randomizer] = field(default_factory=list)
    """Applied in order every frame (scatter after joint randomization, and so on)."""
    writer: WriterCfg = field(default_factory=default_writer_cfg)
    visible_fraction: bool = False
    """Also compute each object's visible fraction (one extra render per visible object)."""
