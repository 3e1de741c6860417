"""RGB-D streams from the simulator for perception: the humanoid's head camera walking the indoor
scene (``head_camera_walk``: under the shipped walking policy or played kinematically) and the gyro
that rides with it (``gyro``)."""

from .gyro import GyroStream
from .head_camera_walk import WALK_MODES, HeadCameraWalk, PolicyHeadCameraWalk, WalkCfg, make_walk

__all__ = ["WALK_MODES", "GyroStream", "HeadCameraWalk", "PolicyHeadCameraWalk", "WalkCfg", "make_walk"]
