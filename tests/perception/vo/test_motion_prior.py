"""The odometry's motion prior from another sensor (``track(..., motion_cam=...)``, leg odometry in
the navigator): before the first keyframe it moves the initial pose, and while lost the pose
coasts on it exactly."""

import numpy as np

from ambulo.perception.vo.config import TrackState
from ambulo.perception.vo.odometry import RgbdOdometry

K = np.array([[200.0, 0, 80], [0, 200.0, 60], [0, 0, 1]])


def _textured():
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 255, (120, 160, 3), dtype=np.uint8)
    return rgb, np.full((120, 160), 2.0, np.float32)


def _blank():
    return np.zeros((120, 160, 3), np.uint8), np.zeros((120, 160), np.float32)


def _step(dx_m):
    out = np.eye(4)
    out[0, 3] = dx_m
    return out


def test_a_late_first_keyframe_starts_where_the_motion_prior_moved_the_camera():
    vo = RgbdOdometry(K)
    assert not vo.track(*_blank()).tracked  # frame 0: nothing to start on, no motion yet
    for _ in range(3):
        result = vo.track(*_blank(), motion_cam=_step(0.1))
        assert not result.tracked
    result = vo.track(*_textured(), motion_cam=_step(0.1))
    assert result.tracked and result.state == TrackState.INITIALIZED
    np.testing.assert_allclose(result.pose_wc[:3, 3], [0.4, 0, 0], atol=1e-12)


def test_lost_the_pose_coasts_on_the_motion_prior():
    vo = RgbdOdometry(K)
    assert vo.track(*_textured()).tracked
    start = vo.pose_wc.copy()
    for k in range(1, 4):
        result = vo.track(*_blank(), motion_cam=_step(0.05))
        assert not result.tracked
        np.testing.assert_allclose(result.pose_wc, start @ _step(0.05 * k), atol=1e-12)
