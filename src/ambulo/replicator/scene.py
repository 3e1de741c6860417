"""The tutorial dataset: the warehouse bay (``ambulo.scenes.warehouse``) seen by the humanoid's head
camera, with its objects scattered, recoloured and lit differently every frame.

The scene is content (``scenes/``); what makes it a dataset (the camera's pose and annotators, the
randomizers) is the replicator's, so it lives here.
"""

from __future__ import annotations

import math

from ambulo.core.randomize import normal, uniform
from ambulo.robots import humanoid
from ambulo.scenes.warehouse import build_warehouse_scene
from ambulo.sensors import CameraCfg

from .config import DATASET_ANNOTATORS, DatasetConfig
from .randomizers import CameraJitter, ColorRandomizer, JointRandomizer, LightRandomizer, MaterialRandomizer
from .scatter import Distractors, Scatter2D


def head_camera_cfg(width: int = 320, height: int = 240) -> CameraCfg:
    """Forward-looking head camera, pitched 20 deg down (world convention: +y rotation pitches down)."""
    pitch = math.radians(20.0)
    return CameraCfg(prim_path=humanoid.HEAD_CAMERA_PRIM, width=width, height=height, fovy_deg=60.0,
                     offset_quat=(math.cos(pitch / 2), 0.0, math.sin(pitch / 2), 0.0),
                     annotators=DATASET_ANNOTATORS)


def example_config(width: int = 320, height: int = 240) -> DatasetConfig:
    """The tutorial dataset: objects and clutter on the floor in front of the robot."""
    region = ((0.3, -1.6), (3.5, 1.6))  # robot at x = -1 looks along +x
    return DatasetConfig(
        name="ambulo_warehouse",
        build_scene=build_warehouse_scene,
        camera=head_camera_cfg(width, height),
        randomizers=[
            JointRandomizer(name="robot_joints", joints="*shoulder*", range_fraction=0.4),
            Scatter2D(name="objects", prims="/World/objects/*", region=region, surface="/World/floor/*"),
            Distractors(name="distractors", region=region, surface="/World/floor/*"),
            ColorRandomizer(name="object_colors", prims="/World/objects/*"),
            MaterialRandomizer(name="object_materials", prims="/World/objects/*"),
            LightRandomizer(name="lights", lights="/World/*"),
            CameraJitter(name="camera_jitter", camera=humanoid.HEAD_CAMERA_PRIM,
                         position_m=normal((0, 0, 0), (0.01, 0.01, 0.01)), rotation_deg=uniform((-4.0, -4.0, -4.0), (4.0, 4.0, 4.0))),
        ],
    )
