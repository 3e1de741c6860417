"""The VO fused with leg odometry (``LegVoLocalizer``) in the navigator: a VO pose that jumps away
from where the legs put the robot is rejected; while the VO is lost the robot walks on the legs'
bridge, which is never fused into the map; past the bridge's limits it stands as before."""

import numpy as np
import pytest

from ambulo.navigation import Navigator, NavigatorCfg, NavWorld, NavWorldCfg
from ambulo.navigation.localization import LegVoLocalizer
from ambulo.perception.vo.config import TrackState
from ambulo.perception.vo.odometry import VoResult

pytest.importorskip("onnxruntime")


class _ScriptedOdometry:
    """A stand-in for ``RgbdOdometry``: the true camera pose, except on ``lost`` frames (LOST, a
    coasted pose 1 m off) and ``jumps`` frames (TRACKING, but 0.6 m off in y: an outlier)."""

    def __init__(self, world, lost=(), jumps=()):
        self.world, self.lost, self.jumps, self.index = world, set(lost), set(jumps), -1
        self.priors = []

    def track(self, rgb, depth, gyro=None, motion_cam=None):
        self.index += 1
        self.priors.append(motion_cam)
        pose = self.world.camera_pose_wc()
        if self.index in self.lost:
            coasted = pose.copy()
            coasted[0, 3] += 1.0
            return VoResult(pose_wc=coasted, state=TrackState.LOST, inliers=0, num_keyframes=1, tracked=False)
        if self.index in self.jumps:
            jumped = pose.copy()
            jumped[1, 3] += 0.6
            return VoResult(pose_wc=jumped, state=TrackState.TRACKING, inliers=200, num_keyframes=1, tracked=True)
        return VoResult(pose_wc=pose, state=TrackState.TRACKING, inliers=200, num_keyframes=1, tracked=True)


def _navigate(room, odometry_args, cfg: NavigatorCfg, seconds: float):
    world = NavWorld.from_file(room, start_pose=(-1.0, 0.0, 0.0),
                               cfg=NavWorldCfg(camera_width=96, camera_height=72))
    odometry = _ScriptedOdometry(world, **odometry_args)
    localizer = LegVoLocalizer(odometry=odometry, bridge_max_m=cfg.bridge_max_m, bridge_max_s=cfg.bridge_max_s)
    nav = Navigator(world, cfg, localizer=localizer)
    fused = []
    real_fuse = nav.mapper.fuse
    nav.mapper.fuse = lambda frame, pose_wc: (fused.append(odometry.index), real_fuse(frame, pose_wc))
    seen = {}
    nav.add_observer(lambda s: seen.__setitem__(odometry.index, (s.estimate, s.true_pose.copy(), s.command, s.status)),
                     images=False)
    nav.set_goal((2.5, 0.0))
    nav.run(max_time_s=seconds)
    world.close()
    return nav, odometry, fused, seen


def test_an_outlier_vo_pose_is_rejected_and_a_bridge_walks_on_unfused(room):
    jumps, lost = {8}, range(18, 28)
    nav, odometry, fused, seen = _navigate(room, {"jumps": jumps, "lost": lost}, NavigatorCfg(mode="full"), 3.0)
    assert nav.localizer.rejected == 1
    est, true, _, _ = seen[8]
    assert est.source == "legs" and est.state == "rejected" and not est.tracked
    assert np.linalg.norm(est.xyyaw[:2] - true[:2]) < 0.05  # the legs' pose, not the 0.6 m jump
    # neither the outlier nor a bridged frame was fused; every VO fix was
    assert not set(fused) & (jumps | set(lost))
    assert len(fused) == nav.frames - len(jumps) - len(lost)
    assert nav.frames_by_source["legs"] == len(jumps) + len(lost) and "none" not in nav.frames_by_source
    for i in lost:
        est, true, command, status = seen[i]
        assert est.source == "legs" and status == "walking"
        assert np.linalg.norm(est.xyyaw[:2] - true[:2]) < 0.05
    # the robot was not told to stand through the bridge (standing commands zero at the next control step)
    assert any(command != (0.0, 0.0, 0.0) for _, _, command, _ in (seen[i] for i in lost))
    # the VO was given the legs' motion as its prior after the first frame
    assert all(p is not None and p.shape == (4, 4) for p in odometry.priors[1:])
    # a VO fix's base pose goes through the torso's joints: with the true camera pose it is the true pose
    fixes = [seen[i] for i in seen if seen[i][0].source == "vo"]
    assert max(np.linalg.norm(est.xyyaw[:2] - true[:2]) for est, true, _, _ in fixes) < 0.02
    assert max(abs(est.xyyaw[2] - true[2]) for est, true, _, _ in fixes) < 0.02


def test_past_the_bridge_limit_the_robot_stands_and_nothing_is_used(room):
    lost = range(5, 20)
    cfg = NavigatorCfg(mode="full", bridge_max_s=0.35, scan_when_lost_after_s=None)
    nav, _, fused, seen = _navigate(room, {"lost": lost}, cfg, 2.2)
    bridged = [i for i in lost if seen[i][0].source == "legs"]
    untracked = [i for i in lost if seen[i][0].source == "none"]
    assert 2 <= len(bridged) <= 4 and bridged == list(lost)[:len(bridged)]
    assert untracked == [i for i in lost if i > max(bridged) and i in seen]
    assert nav.untracked_frames == len(untracked) and nav.frames_by_source["none"] == len(untracked)
    assert not set(fused) & set(lost)
    for i in untracked[1:]:
        est, _, command, status = seen[i]
        assert status == "lost" and command == (0.0, 0.0, 0.0)
        np.testing.assert_allclose(est.xyyaw, seen[untracked[0]][0].xyyaw)  # held, not moved by the legs
