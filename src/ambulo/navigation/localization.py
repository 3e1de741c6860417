"""Localizers: where the navigator thinks the robot is.

- ``OracleLocalizer``: the simulator's pose, every physics step (always tracked).
- ``VoLocalizer``: ``perception.vo.RgbdOdometry`` on the head camera's RGB-D frames with the head
  gyro, started at the true first pose (so its estimate lives in the world frame). Each frame is
  **tracked** or not: tracked when the odometry measured the pose from the image (``TRACKING``,
  ``RECOVERED``, the first frame) and **untracked** when it only coasted it (``LOST``) or restarted
  its map at a coasted pose (``REINITIALIZED``, that frame). While untracked the estimate is not
  updated at all: the navigator must neither steer on nor fuse a coasted pose.

The base pose (x, y, yaw of the pelvis on the floor) comes from the camera pose through the
pelvis's pose in the camera frame measured once at the start (the head turns little on the
pelvis, so the error is the head's sway: a few cm).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..perception.frames import RgbdFrame
from ..perception.vo.config import TrackState, VoCfg, head_camera_vo_cfg
from ..perception.vo.odometry import RgbdOdometry
from ..utils.validate import Checked
from .world import NavWorld

TRACKED_STATES = (TrackState.INITIALIZED, TrackState.TRACKING, TrackState.RECOVERED)
"""VO states whose pose was measured from the image (module docstring)."""


@dataclass
class PoseEstimate:
    """One localization result."""

    xyyaw: np.ndarray
    """(3,) base pose estimate (x m, y m, yaw rad), world frame."""
    tracked: bool
    time_s: float
    pose_wc: np.ndarray | None = None
    """(4, 4) the camera-to-world pose the estimate came from (what a mapper fuses at); None for
    estimates between frames."""
    state: str = "tracking"
    """The localizer's own word for it (the VO's ``TrackState`` value)."""


def xyyaw_from_matrix(pose: np.ndarray) -> np.ndarray:
    return np.array([pose[0, 3], pose[1, 3], math.atan2(pose[1, 0], pose[0, 0])])


def is_tracked(result) -> bool:
    """A VO result's tracked flag: its own ``tracked`` if it has one, else its state."""
    flag = getattr(result, "tracked", None)
    return bool(flag) if flag is not None else result.state in TRACKED_STATES


class OracleLocalizer:
    """Ground truth (module docstring)."""

    name = "oracle"
    needs_images = False

    def reset(self, world: NavWorld) -> None:
        self.world = world

    def pose(self) -> np.ndarray:
        return self.world.true_pose()

    def on_frame(self, frame: RgbdFrame | None) -> PoseEstimate:
        pose_wc = frame.pose_wc.numpy() if frame is not None else None
        return PoseEstimate(self.world.true_pose(), True, self.world.time_s, pose_wc, "oracle")


@dataclass(kw_only=True)
class VoLocalizerCfg(Checked):
    vo: VoCfg = field(default_factory=head_camera_vo_cfg)
    """ORB tuned for the small, low-contrast head camera (the defaults lose track facing the
    apartments' walls; ``head_camera_vo_cfg`` gives the figures)."""
    use_gyro: bool = True


class VoLocalizer:
    """Visual odometry with the gyro (module docstring). ``odometry``: a ready ``RgbdOdometry``-like
    object (``track(rgb, depth, gyro) -> VoResult``) instead of one built at ``reset``."""

    name = "vo"
    needs_images = True

    def __init__(self, cfg: VoLocalizerCfg | None = None, odometry=None):
        self.cfg = cfg or VoLocalizerCfg()
        self._given = odometry

    def reset(self, world: NavWorld) -> None:
        self.world = world
        self.vo = self._given
        self._base_in_cam = world.base_in_camera()
        self._pose_cam_imu = world.pose_cam_imu() if self.cfg.use_gyro else None
        self._xyyaw = world.true_pose()
        self.tracked = True
        self.last = None

    def pose(self) -> np.ndarray:
        """The last tracked estimate (held between frames and while untracked)."""
        return self._xyyaw

    def on_frame(self, frame: RgbdFrame) -> PoseEstimate:
        if self.vo is None:
            self.vo = RgbdOdometry(frame.intrinsics.numpy(), self.cfg.vo, initial_pose_wc=frame.pose_wc.numpy(),
                                   pose_cam_imu=self._pose_cam_imu)
        gyro = frame.gyro if self.cfg.use_gyro else None
        result = self.vo.track(frame.rgb.numpy(), frame.depth_m.numpy(), gyro=gyro)
        self.last = result
        self.tracked = is_tracked(result)
        state = getattr(result.state, "value", str(result.state))
        if not self.tracked:
            return PoseEstimate(self._xyyaw.copy(), False, frame.time_s, None, state)
        pose_wc = np.asarray(result.pose_wc, float)
        self._xyyaw = xyyaw_from_matrix(pose_wc @ self._base_in_cam)
        return PoseEstimate(self._xyyaw.copy(), True, frame.time_s, pose_wc, state)


__all__ = ["OracleLocalizer", "PoseEstimate", "TRACKED_STATES", "VoLocalizer", "VoLocalizerCfg", "is_tracked",
           "xyyaw_from_matrix"]
