"""The tutorial scene: a warehouse bay, a humanoid with a head camera, scattered labelled objects.

Built with the core scene builder (``ambulo.core.scene``: the same ground, lights and robot
importer as ``World`` and the RL tasks; z up, metres); object bodies are named by prim path
(``/World/objects/box_0``) and labelled for COCO with ``ambulo.core.set_semantic_label``.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from ambulo.core import GroundCfg, RobotCfg, add_ground, add_light, add_robot, new_scene, set_semantic_label
from ambulo.core.randomize import normal, uniform
from ambulo.robots import humanoid
from ambulo.sensors import CameraCfg

from .config import DATASET_ANNOTATORS, DatasetConfig
from .randomizers import CameraJitter, ColorRandomizer, JointRandomizer, LightRandomizer, MaterialRandomizer
from .scatter import Distractors, Scatter2D

ROOM_HALF_M = 6.0
WALL_HEIGHT_M = 3.0
# (label, geom type, size) of the scattered objects; sizes are MuJoCo half-sizes/radii (m)
OBJECTS = [
    ("box", "box", (0.20, 0.15, 0.15)), ("box", "box", (0.25, 0.25, 0.20)), ("box", "box", (0.15, 0.10, 0.10)),
    ("box", "box", (0.30, 0.20, 0.12)), ("can", "cylinder", (0.08, 0.12)), ("can", "cylinder", (0.10, 0.18)),
    ("can", "cylinder", (0.06, 0.10)), ("ball", "sphere", (0.12,)), ("ball", "sphere", (0.18,)),
    ("cone", "ellipsoid", (0.12, 0.12, 0.25)),
]


def _geom_type(name: str) -> int:
    return getattr(mujoco.mjtGeom, f"mjGEOM_{name.upper()}")


def build_warehouse_scene() -> mujoco.MjSpec:
    spec = new_scene("ambulo_warehouse")
    # software rasterizers pay per triangle: coarser spheres/capsules and no headlight
    # (the scene's own lights are randomized) halve the render time at 320x240
    spec.visual.quality.numslices, spec.visual.quality.numstacks = 16, 8
    spec.visual.headlight.active = 0
    # 2 m render grid: a 0.1 m grid is 14,400 quads
    add_ground(spec, GroundCfg(prim_path="/World/floor", size_m=2 * ROOM_HALF_M, render_grid_m=2.0,
                               checker_m=0.75, color=(0.42, 0.42, 0.40), sky=False, sun=False))
    world = spec.worldbody
    for i, (x, y, sx, sy) in enumerate([(ROOM_HALF_M, 0, 0.1, ROOM_HALF_M), (-ROOM_HALF_M, 0, 0.1, ROOM_HALF_M),
                                        (0, ROOM_HALF_M, ROOM_HALF_M, 0.1), (0, -ROOM_HALF_M, ROOM_HALF_M, 0.1)]):
        world.add_geom(name=f"/World/wall_{i}", type=mujoco.mjtGeom.mjGEOM_BOX, pos=[x, y, WALL_HEIGHT_M / 2],
                       size=[sx, sy, WALL_HEIGHT_M / 2], rgba=[0.75, 0.74, 0.70, 1])
    _add_shelves(world)
    add_light(spec, "/World/sun", kind="distant", position=(0, 0, WALL_HEIGHT_M), direction=(0.3, 0.2, -1),
              intensity=0.7, ambient=0.2)
    add_light(spec, "/World/lamp", kind="sphere", position=(2.0, 0, WALL_HEIGHT_M - 0.2), intensity=0.3)
    add_robot(spec, RobotCfg(file=humanoid.ASSET, prim_path=humanoid.PRIM_PATH, pos_m=(-1.0, 0.0, 0.0)))
    for i, (label, kind, size) in enumerate(OBJECTS):
        body = world.add_body(name=f"/World/objects/{label}_{i}", pos=[0, 0, -10.0 - 3.0 * i])
        body.add_freejoint()
        body.add_geom(type=_geom_type(kind), size=list(size) + [0] * (3 - len(size)), rgba=[0.6, 0.5, 0.3, 1])
        set_semantic_label(spec, body.name, label)
    return spec


def _add_shelves(world) -> None:
    """Two pallet racks along the side walls: uprights and three shelf levels each."""
    for side in (-1, 1):
        y = side * (ROOM_HALF_M - 0.6)
        for level in (0.05, 0.9, 1.75):
            world.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, pos=[1.5, y, level], size=[3.0, 0.45, 0.03],
                           rgba=[0.55, 0.35, 0.15, 1])
        for x in np.linspace(-1.5, 4.5, 5):
            for dy in (-0.42, 0.42):
                world.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, pos=[x, y + dy, 1.0], size=[0.04, 0.04, 1.0],
                               rgba=[0.15, 0.3, 0.6, 1])


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
