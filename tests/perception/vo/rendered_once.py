"""A kinematic head-camera walk whose frames are rendered once and replayed: several VO tests run
the same walk (same scene, size and ``WalkCfg``) with different odometry settings or losses, and the
rendering (llvmpipe on CI's CPU) costs more than the tracking at 640x480."""

from __future__ import annotations

import dataclasses

from ambulo.perception.frames import RgbdFrame
from ambulo.perception.sources.head_camera_walk import HeadCameraWalk


class RenderedOnce:
    """``HeadCameraWalk``'s ``frame`` / ``walk`` / ``pose_cam_imu`` for ``run_walk_vo``, each frame
    rendered on first use. Replaying is exact: the kinematic walk's frame ``i`` depends on ``i`` only
    (its pose is a function of time and its gyro noise is replayed from the start when frames are
    asked out of order), which ``test_a_replayed_frame_is_the_rendered_one`` checks.

    Memory: 0.54 MB a frame at 320x240, 2.2 MB at 640x480 (uint8 RGB + float32 depth)."""

    def __init__(self, walk: HeadCameraWalk):
        self.source = walk
        self._frames: dict[int, RgbdFrame] = {}

    @property
    def walk(self):
        return self.source.walk

    @property
    def pose_cam_imu(self):
        return self.source.pose_cam_imu

    def frame(self, index: int) -> RgbdFrame:
        if index not in self._frames:
            self._frames[index] = self.source.frame(index)
        f = self._frames[index]
        # copies: a consumer that writes into its images must not change the next test's frames
        return dataclasses.replace(f, rgb=f.rgb.clone(), depth_m=f.depth_m.clone())

    def close(self) -> None:
        """Kept open: the fixture that made it closes the walk after the last test that reads it."""

    def release(self) -> None:
        self._frames.clear()
        self.source.close()
