"""Synthetic data: randomized scenes, annotated frames, COCO/KITTI/raw writers, resumable generation.

A dataset is declared as a ``DatasetConfig``::

    from ambulo import replicator as rep

    config = rep.DatasetConfig(
        build_scene=my_scene,                      # -> mujoco.MjSpec with semantic labels
        camera=rep.head_camera_cfg(320, 240),
        randomizers=[
            rep.Scatter2D(name="objects", prims="/World/objects/*", region=((0, -1), (3, 1))),
            rep.ColorRandomizer(name="colors", prims="/World/objects/*"),
            rep.LightRandomizer(name="lights", intensity=rep.uniform(0.3, 1.0)),
        ],
    )
    rep.generate(config, "out/", num_frames=100, seed=0)
"""

from ambulo.core.randomize import choice, constant, normal, uniform, uniform_int

from .coco import coco_categories, frame_annotations, merge_coco
from .config import DATASET_ANNOTATORS, DatasetConfig
from .generate import generate
from .producer import FrameProducer, run_frames
from .randomizers import (
                          CameraJitter,
                          ColorRandomizer,
                          JointRandomizer,
                          LightRandomizer,
                          MaterialRandomizer,
                          Randomizer,
                          SceneContext,
)
from .scatter import CollisionChecker, Distractors, Scatter2D
from .scene import build_warehouse_scene, example_config, head_camera_cfg
from .writers import WRITERS, WriterCfg, default_writer_cfg

__all__ = [
                          "DATASET_ANNOTATORS",
                          "WRITERS",
                          "CameraJitter",
                          "CollisionChecker",
                          "ColorRandomizer",
                          "DatasetConfig",
                          "Distractors",
                          "FrameProducer",
                          "JointRandomizer",
                          "LightRandomizer",
                          "MaterialRandomizer",
                          "Randomizer",
                          "Scatter2D",
                          "SceneContext",
                          "WriterCfg",
                          "build_warehouse_scene",
                          "choice",
                          "coco_categories",
                          "constant",
                          "default_writer_cfg",
                          "example_config",
                          "frame_annotations",
                          "generate",
                          "head_camera_cfg",
                          "merge_coco",
                          "normal",
                          "run_frames",
                          "uniform",
                          "uniform_int",
]
