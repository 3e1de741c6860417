"""Run visual odometry on the humanoid's head-camera walk and score it: TUM files for evo, ATE /
RPE, and how fast tracking comes back after an injected loss: a covered lens (black colour, no
depth), a textureless wall in front of the lens (uniform grey, depth 0.5 m everywhere: depth but no
feature) or a fast head turn (``WalkCfg.look_away``, rendered by the walk itself)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from ..trajectory import TrajectoryScore, score_tum, write_tum
from .config import TrackState, VoCfg
from .odometry import RgbdOdometry

if TYPE_CHECKING:  # named only: the walks (sources/) take their gyro type from vo/, so vo/ must not import them
    from ..sources.head_camera_walk import HeadCameraWalk, PolicyHeadCameraWalk


@dataclass
class VoRun:
    times_s: np.ndarray
    estimate_wc: np.ndarray
    """(N, 4, 4) estimated poses."""
    truth_wc: np.ndarray
    """(N, 4, 4) ground-truth poses of the head camera."""
    states: list[TrackState]
    vo_ms: list[float]
    """Per-frame odometry time (features, matching, PnP, refinement), ms."""
    blackout: tuple[int, int] | None
    """[start, end) frames during which tracking could not work (covered lens, textureless wall, a
    fast turn away from everything mapped)."""
    tracked: np.ndarray | None = None
    """(N,) bool ``VoResult.tracked`` of each frame (None: every pose counts as tracked)."""

    @property
    def untracked_frames(self) -> int:
        """Frames whose pose was coasted, not measured (left out of ``score``)."""
        return 0 if self.tracked is None else int((~self.tracked).sum())

    def recovery_frames(self, tolerance_m: float = 0.05) -> int | None:
        """Frames after the loss until the state is tracking/recovered again with a position
        error below ``tolerance_m``; None without a loss or if it never recovers."""
        if self.blackout is None:
            return None
        end, error_m = self.blackout[1], self.position_error_m()
        for i in range(end, len(self.states)):
            ok = self.states[i] in (TrackState.TRACKING, TrackState.RECOVERED)
            if ok and error_m[i] < tolerance_m:
                return i - end
        return None

    def position_error_m(self) -> np.ndarray:
        """(N,) distance between the estimated and the true camera positions, m."""
        return np.linalg.norm(self.estimate_wc[:, :3, 3] - self.truth_wc[:, :3, 3], axis=1)

    def rotation_error_deg(self) -> np.ndarray:
        """(N,) angle of the rotation between the estimated and the true camera orientations, deg."""
        rel = np.transpose(self.estimate_wc[:, :3, :3], (0, 2, 1)) @ self.truth_wc[:, :3, :3]
        return np.degrees(np.linalg.norm(Rotation.from_matrix(rel).as_rotvec(), axis=1))

    def write(self, folder: str | Path) -> tuple[Path, Path]:
        """``groundtruth.tum`` (every frame), ``estimate.tum`` (the tracked frames' poses) and
        ``estimate_all.tum`` (every frame's, coasted ones included) in ``folder``; returns the first two."""
        folder = Path(folder)
        keep = np.ones(len(self.times_s), bool) if self.tracked is None else self.tracked
        write_tum(folder / "estimate_all.tum", self.times_s, self.estimate_wc)
        return (write_tum(folder / "groundtruth.tum", self.times_s, self.truth_wc),
                write_tum(folder / "estimate.tum", self.times_s[keep], self.estimate_wc[keep]))

    def score(self, folder: str | Path) -> TrajectoryScore:
        """Write the trajectories into ``folder`` and score the tracked poses (``trajectory.score_tum``:
        a run too short or too still to align or to span the RPE's metre gets None with the reason); the
        untracked ones are ``untracked_frames``, their errors ``position_error_m``."""
        gt, est = self.write(folder)
        return score_tum(gt, est)


LOSSES = ("covered_lens", "textureless_wall", "motion")
"""Losses in ``run_walk_vo``'s window: the first two are injected into the frames; ``motion`` injects
nothing (the walk itself loses the view, e.g. a fast turn, ``WalkCfg.look_away``): the window only
says from which frame on recovery is counted."""


def run_walk_vo(walk: HeadCameraWalk | PolicyHeadCameraWalk, num_frames: int, cfg: VoCfg | None = None,
                blackout: tuple[int, int] | None = None, progress=None, loss: str = "covered_lens",
                imu: bool = False) -> VoRun:
    """Render ``num_frames`` of ``walk`` and track them; frames in ``blackout`` [start, end) are
    replaced by the ``loss`` (``LOSSES``; the gyro is not affected). The estimate starts at the true
    first pose (the simulator's world). ``imu``: pass the walk's gyro readings to the odometry."""
    if loss not in LOSSES:
        raise ValueError(f"loss={loss!r} is not one of {LOSSES}")
    if num_frames < 1:
        raise ValueError(f"num_frames is {num_frames}: a run needs at least 1 frame; pass e.g. num_frames=300")
    times, est, truth, states, vo_ms, tracked = [], [], [], [], [], []
    vo = None
    for i in range(num_frames):
        frame = walk.frame(i)
        rgb, depth = frame.rgb.numpy(), frame.depth_m.numpy()
        if blackout is not None and blackout[0] <= i < blackout[1]:
            if loss == "covered_lens":
                rgb, depth = np.zeros_like(rgb), np.zeros_like(depth)
            elif loss == "textureless_wall":  # a plain wall filling the view half a metre away
                rgb, depth = np.full_like(rgb, 128), np.full_like(depth, 0.5)
        if vo is None:
            vo = RgbdOdometry(frame.intrinsics.numpy(), cfg, initial_pose_wc=frame.pose_wc.numpy(),
                              pose_cam_imu=walk.pose_cam_imu if imu else None)
        t0 = time.perf_counter()
        result = vo.track(rgb, depth, gyro=frame.gyro if imu else None)
        vo_ms.append((time.perf_counter() - t0) * 1e3)
        times.append(frame.time_s)
        est.append(result.pose_wc)
        truth.append(frame.pose_wc.numpy())
        states.append(result.state)
        tracked.append(result.tracked)
        if progress is not None:
            progress(i)
    return VoRun(np.array(times), np.array(est), np.array(truth), states, vo_ms, blackout, np.array(tracked, bool))


__all__ = ["LOSSES", "VoRun", "run_walk_vo"]
