"""The gyro aid of the visual odometry: integration and bias math by hand, then what it changes on
the humanoid's head-camera walk (a turn too fast for the images, a blackout while walking on), and
the new map started when relocalisation keeps failing."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ambulo.perception.sources.head_camera_walk import HeadCameraWalk, PolicyHeadCameraWalk, WalkCfg
from ambulo.perception.vo.config import TrackState, VoCfg
from ambulo.perception.vo.eval import run_walk_vo
from ambulo.perception.vo.imu import GyroAid, GyroSamples, integrate_gyro
from ambulo.perception.vo.odometry import RgbdOdometry
from ambulo.scenes.indoor import build_indoor_scene
from ambulo.sensors.imu_noise import noiseless
from ambulo.utils.checks import InvalidValueError

pytest.importorskip("cv2", reason="the perception extra is not installed")


def rot_x(deg):
    return Rotation.from_euler("x", deg, degrees=True).as_matrix()


def rot_z(deg):
    return Rotation.from_euler("z", deg, degrees=True).as_matrix()


def test_a_constant_rate_integrates_to_its_rotation_and_the_bias_comes_off():
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    times = np.linspace(0.0, 0.5, 101)
    rates = np.tile(axis * math.pi, (101, 1))  # 180 deg/s for 0.5 s: 90 deg about the axis
    expected = Rotation.from_rotvec(axis * math.pi / 2).as_matrix()
    np.testing.assert_allclose(integrate_gyro(GyroSamples(times, rates)), expected, atol=1e-12)
    bias = np.array([0.01, -0.02, 0.03])
    np.testing.assert_allclose(integrate_gyro(GyroSamples(times, rates + bias), bias), expected, atol=1e-12)


def test_increments_compose_in_the_body_frame():
    """90 deg about x, then 90 deg about the (new) z: R = Rx(90) Rz(90), not Rz(90) Rx(90)."""
    t1 = np.linspace(0.0, 1.0, 51)
    t2 = np.linspace(1.0 + 1e-9, 2.0, 51)
    rates = np.concatenate([np.tile([math.pi / 2, 0, 0], (51, 1)), np.tile([0, 0, math.pi / 2], (51, 1))])
    rot = integrate_gyro(GyroSamples(np.concatenate([t1, t2]), rates))
    np.testing.assert_allclose(rot, rot_x(90) @ rot_z(90), atol=1e-6)
    assert not np.allclose(rot, rot_z(90) @ rot_x(90), atol=0.1)


def test_the_extrinsic_carries_the_imu_rotation_into_the_camera_frame():
    """The IMU turned -90 deg about the camera's x: Rx(-90) (0, 0, 1) = (0, 1, 0), the IMU's z is the
    camera's y, so a turn about the IMU's z is the same turn about the camera's y."""
    aid = GyroAid(rot_x(-90), bias_gain=0.0)
    samples = GyroSamples([0.0, 0.1], [[0, 0, 1.0], [0, 0, 1.0]])  # 0.1 rad about z_imu
    np.testing.assert_allclose(aid.camera_rotation(samples),
                               Rotation.from_rotvec([0, 0.1, 0]).as_matrix(), atol=1e-12)


def test_the_bias_estimate_converges_to_the_true_bias():
    """Rates read ``w + b``; each frame the odometry's (here exact) rotation corrects the estimate by
    ``gain`` of the residual: after 300 frames, (1 - 0.02)^300 = 0.2 % of the bias is left."""
    rng = np.random.default_rng(0)
    bias = np.radians([0.8, -0.15, -1.1])
    aid = GyroAid(rot_x(30) @ rot_z(-50), bias_gain=0.02)
    for _ in range(300):
        rate = rng.normal(0.0, 0.5, 3)
        truth_imu = Rotation.from_rotvec(rate / 30).as_matrix()
        truth_cam = aid.rot_cam_imu @ truth_imu @ aid.rot_cam_imu.T
        aid.update_bias(GyroSamples(np.linspace(0, 1 / 30, 8), np.tile(rate + bias, (8, 1))), truth_cam)
    np.testing.assert_allclose(aid.bias_rad_s, bias, rtol=0.01)


def test_bad_gyro_input_is_refused_in_one_line():
    with pytest.raises(InvalidValueError, match="at least 2"):
        GyroSamples([0.0], [[0, 0, 0]])
    with pytest.raises(InvalidValueError, match="not all finite"):
        GyroSamples([0.0, 0.01], [[0, 0, 0], [0, float("nan"), 0]])
    with pytest.raises(InvalidValueError, match="times must increase"):
        GyroSamples([0.0, 0.0], [[0, 0, 0], [0, 0, 0]])
    with pytest.raises(InvalidValueError, match="pose_cam_imu"):
        RgbdOdometry(np.eye(3), VoCfg(), pose_cam_imu=np.diag([1.0, 1.0, -1.0]))  # a reflection
    vo = RgbdOdometry(np.eye(3), VoCfg())
    with pytest.raises(ValueError, match="pass pose_cam_imu"):
        vo.track(np.zeros((8, 8, 3), np.uint8), np.zeros((8, 8)), gyro=GyroSamples([0, 1], [[0, 0, 0], [0, 0, 0]]))


@pytest.mark.parametrize("walk_cls", [HeadCameraWalk, PolicyHeadCameraWalk], ids=["kinematic", "policy"])
def test_the_walks_gyro_matches_the_camera_rotation(walk_cls):
    """Noiseless, the gyro integrated between frames and carried through the walk's extrinsic is the
    camera's true rotation between them (the policy walk: MuJoCo's gyro at the mount site)."""
    walk = walk_cls(build_indoor_scene(), WalkCfg(imu_noise=noiseless()), width=80, height=60)
    aid, prev, worst = None, None, 0.0
    for i in range(40):
        frame = walk.frame(i)
        pose = frame.pose_wc.numpy()
        if prev is not None:
            aid = aid or GyroAid(walk.pose_cam_imu, 0.0)
            truth = prev[:3, :3].T @ pose[:3, :3]
            worst = max(worst, np.degrees(np.linalg.norm(
                Rotation.from_matrix(truth.T @ aid.camera_rotation(frame.gyro)).as_rotvec())))
        prev = pose
    walk.close()
    assert frame.gyro.duration_s == pytest.approx(1 / 30, abs=0.006)
    # deg over a frame. Kinematic: each sample is the exact mean rate of its interval. Policy: MuJoCo
    # turns each joint of the chain by its own rate, so the head's turn over a 5 ms step is exp(w dt)
    # only to second order (0.005 deg a frame measured; the trapezoid rule on these samples: 0.12)
    assert worst < (1e-6 if walk_cls is HeadCameraWalk else 0.01)


def test_through_a_turn_too_fast_for_the_images_the_gyro_keeps_the_pose(walk_vo_run):
    """180 deg away and back in 0.4 s (peak 1400 deg/s): the images lose track either way; with the
    walk's noisy gyro (EuRoC's ADIS16448, 0.5 deg/s turn-on bias) the coasted heading stays within
    a degree (measured 0.23) instead of facing the wrong way, and the position error more than
    halves (measured 6.1 cm against 15.5 cm)."""
    errors = {}
    for imu in (False, True):
        # without the gyro: test_odometry's run of this turn (imu=False is run_walk_vo's default)
        kwargs = {"imu": True} if imu else {}
        run = walk_vo_run(320, 240, WalkCfg(look_away=(2.0, 0.4, math.pi)), 102, blackout=(60, 72), loss="motion",
                          **kwargs)
        assert TrackState.LOST in run.states[60:72]
        frames = run.recovery_frames(tolerance_m=0.05)
        assert frames is not None and frames <= 30
        errors[imu] = (run.rotation_error_deg()[60:72].max(), run.position_error_m().max())
    assert errors[False][0] > 90 and errors[True][0] < 1
    assert errors[True][1] < 0.08 and errors[True][1] < 0.6 * errors[False][1]


def test_after_a_blackout_round_a_corner_a_new_map_keeps_tracking(rendered_walk):
    """1 s of covered lens while walking into a corner (frames 100-130 at 320x240): the first frames
    after it share too little with any keyframe to relocalise. Without a new map the odometry stays
    lost (the error grows with the walk); with it, tracking goes on within
    ``reinit_after_lost_frames`` and the error stays what the blind second left. With the gyro that
    error starts with the heading right."""
    walk = rendered_walk(320, 240)
    stuck = run_walk_vo(walk, 200, VoCfg(reinit_after_lost_frames=10_000), blackout=(100, 130))
    assert all(s == TrackState.LOST for s in stuck.states[100:])  # the case this guards against
    for imu in (False, True):
        run = run_walk_vo(walk, 200, blackout=(100, 130), imu=imu)
        states = run.states[130:]
        back = states.index(TrackState.REINITIALIZED)
        assert back <= VoCfg().reinit_after_lost_frames
        assert all(s == TrackState.TRACKING for s in states[back + 1:])
        err = run.position_error_m()
        assert err[-1] - err[130 + back] < 0.04  # tracking again: 2.3 s of walk add little
        if imu:
            assert run.rotation_error_deg()[130 + back] < 1.0
