"""Issue 24: a camera pose estimate with a small pitch / roll / height error is levelled on the
floor its depth frame sees (the far floor it would otherwise put into the occupancy band), and
left alone when the frame shows no floor to trust."""

import math

import numpy as np
import pytest

from ambulo.navigation import Navigator, NavigatorCfg, NavWorld, NavWorldCfg
from ambulo.navigation.floor_level import FloorLevelCfg, level_on_floor

K = np.array([[262.5, 0.0, 159.5], [0.0, 262.5, 119.5], [0.0, 0.0, 1.0]])


def _camera(x, y, z, yaw, pitch_down, roll=0.0):
    """(4, 4) camera-to-world (OpenCV axes: x right, y down, z forward) looking along ``yaw``,
    pitched down by ``pitch_down`` and rolled by ``roll`` about its optical axis."""
    fwd = np.array([math.cos(yaw) * math.cos(pitch_down), math.sin(yaw) * math.cos(pitch_down), -math.sin(pitch_down)])
    right = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
    rot = np.stack([right, np.cross(fwd, right), fwd], 1)
    c, s = math.cos(roll), math.sin(roll)
    pose = np.eye(4)
    pose[:3, :3] = rot @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    pose[:3, 3] = (x, y, z)
    return pose


def _depth_of_plane(pose_wc, normal, offset, shape=(240, 320)):
    """Depth (z) of the plane normal . p + offset = 0 seen from ``pose_wc`` (0 where not in front)."""
    v, u = np.mgrid[0:shape[0], 0:shape[1]]
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones(shape)], -1)  # z = 1
    dirs = rays @ pose_wc[:3, :3].T
    denom = dirs @ normal
    t = -(pose_wc[:3, 3] @ normal + offset) / np.where(np.abs(denom) > 1e-9, denom, np.nan)
    return np.where(np.isfinite(t) & (t > 0), t, 0.0).astype(np.float32)


def _elevation_roll_deg(pose):
    fwd, right = pose[:3, 2], pose[:3, 0]
    return math.degrees(math.asin(fwd[2])), math.degrees(math.asin(right[2]))


def test_a_tilted_estimate_is_levelled_on_the_floor_it_sees():
    truth = _camera(1.0, 2.0, 1.45, 0.7, math.radians(25))
    depth = _depth_of_plane(truth, np.array([0.0, 0.0, 1.0]), 0.0)
    rng = np.random.default_rng(3)
    depth *= (1.0 + 0.01 * rng.standard_normal(depth.shape)).astype(np.float32)  # 1 % of range
    depth[:50, :90] *= 0.93  # something standing on the floor in a corner of the view
    estimate = _camera(1.03, 1.98, 1.42, 0.71, math.radians(25.6), math.radians(0.4))
    fit = level_on_floor(depth, K, estimate)
    assert fit is not None and fit.num_points > 1000
    el_t, roll_t = _elevation_roll_deg(truth)
    el_e, roll_e = _elevation_roll_deg(estimate)
    el_l, roll_l = _elevation_roll_deg(fit.pose_wc)
    assert abs(el_e - el_t) > 0.5 and abs(el_l - el_t) < 0.1  # the 0.6 deg pitch error is gone
    assert abs(roll_e - roll_t) > 0.3 and abs(roll_l - roll_t) < 0.1
    assert abs(fit.pose_wc[2, 3] - 1.45) < 0.01  # the height too
    np.testing.assert_allclose(fit.pose_wc[:2, 3], estimate[:2, 3])  # x, y as estimated
    # the far floor now lies at z = 0: 4 m ahead it was ~4 cm up under the estimate
    far = (depth > 3.5) & (depth < 4.0)
    v, u = np.nonzero(far)
    z = depth[v, u]
    p_c = np.stack([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z], -1)
    clean = v >= 50
    assert np.abs(np.median((p_c @ estimate[:3, :3].T + estimate[:3, 3])[clean, 2])) > 0.02
    assert np.abs(np.median((p_c @ fit.pose_wc[:3, :3].T + fit.pose_wc[:3, 3])[clean, 2])) < 0.005


def test_no_floor_in_view_or_a_ramp_leaves_the_pose_alone():
    pose = _camera(0.0, 0.0, 1.45, 0.0, math.radians(5))
    wall = _depth_of_plane(pose, np.array([1.0, 0.0, 0.0]), -2.0)  # a wall 2 m ahead, no floor
    assert level_on_floor(wall, K, pose) is None
    down = _camera(0.0, 0.0, 1.45, 0.0, math.radians(25))
    strip = _depth_of_plane(down, np.array([0.0, 0.0, 1.0]), 0.0)
    strip[:, :145] = 0.0
    strip[:, 175:] = 0.0  # a strip of floor (down a corridor) pins the pitch, not the roll
    assert level_on_floor(strip, K, down) is None
    assert level_on_floor(strip, K, down, FloorLevelCfg(min_extent_m=0.0)) is not None
    tilt = math.radians(4.5)  # a ramp rising 4.5 deg ahead is not an estimate's error
    ramp = _depth_of_plane(down, np.array([-math.sin(tilt), 0.0, math.cos(tilt)]), 0.0)
    cfg = FloorLevelCfg(near_floor_m=0.4)  # all of the ramp in view is a candidate: only the tilt refuses it
    assert level_on_floor(ramp, K, down, cfg) is None
    assert level_on_floor(ramp, K, down, FloorLevelCfg(near_floor_m=0.4, max_tilt_rad=0.1)) is not None


def test_the_navigator_fuses_a_vo_pose_levelled_on_the_floor_and_the_oracle_pose_as_it_is(room):
    pytest.importorskip("onnxruntime")
    world = NavWorld.from_file(room, start_pose=(-1.0, 0.0, 0.0),
                               cfg=NavWorldCfg(camera_width=160, camera_height=120, record_gyro=False))
    frame = world.capture()
    truth = frame.pose_wc.numpy()
    a = math.radians(0.7)  # the estimate pitched 0.7 deg about the world's y axis, 3 cm low
    pitch = np.array([[math.cos(a), 0.0, math.sin(a)], [0.0, 1.0, 0.0], [-math.sin(a), 0.0, math.cos(a)]])
    estimate = truth.copy()
    estimate[:3, :3] = pitch @ truth[:3, :3]
    estimate[2, 3] -= 0.03
    full = Navigator(world, NavigatorCfg(mode="full"))
    fused = full._levelled(frame, estimate)
    err = math.degrees(math.acos(np.clip((np.trace(fused[:3, :3].T @ truth[:3, :3]) - 1) / 2, -1, 1)))
    assert err < 0.15 and abs(fused[2, 3] - truth[2, 3]) < 0.01, (err, fused[2, 3] - truth[2, 3])
    assert full.floor_tilts_rad and full.floor_tilts_rad[-1] > math.radians(0.5)
    oracle = Navigator(world, NavigatorCfg(mode="mapping"))
    assert oracle._levelled(frame, estimate) is estimate  # a true pose is fused as it is
    world.close()
