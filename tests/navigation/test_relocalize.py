"""Relocalisation against the map (``relocalize``) and the fused localizer that asks it: the head
camera's depth in an apartment (seed 1000) is matched on the apartment's occupancy map."""

import math

import numpy as np
import pytest

from ambulo.navigation import NavWorld, NavWorldCfg
from ambulo.navigation.localization import LegVoLocalizer
from ambulo.navigation.relocalize import RelocalizeCfg, apply_correction, look_yaw_rad, match_scan, scan_xy_m
from ambulo.perception.vo.config import TrackState
from ambulo.perception.vo.odometry import VoResult
from ambulo.scenes import apartment

FACING_ROOM = (4.3, 2.0, -math.pi / 2)
"""Apartment 1000: in the doorway between its two right rooms, looking down the room (walls,
a door, furniture in view)."""
FACING_WALL = (4.3, 3.1, math.pi / 2)
"""The same room's north wall 0.6 m ahead: one bare plane in view."""


@pytest.fixture(scope="module")
def apt():
    return apartment(1000)


def _world(apt, pose):
    return NavWorld.from_apartment(apt, pose, NavWorldCfg())


def _shifted(pose_wc, correction):
    """The camera pose moved by the planar ``correction`` (dx, dy, dyaw) about its own position."""
    out = pose_wc.copy()
    c, s = math.cos(correction[2]), math.sin(correction[2])
    rot = np.array([[c, -s], [s, c]])
    out[:2, :3] = rot @ pose_wc[:2, :3]
    out[:2, 3] = pose_wc[:2, 3] + correction[:2]
    return out


@pytest.mark.parametrize("offset", [(0.0, 0.0, 0.0), (0.4, -0.3, 0.05), (-0.8, 0.5, -0.07)])
def test_a_frame_matched_from_a_wrong_guess_finds_the_true_pose(apt, offset):
    world = _world(apt, FACING_ROOM)
    frame = world.capture()
    world.close()
    truth = frame.pose_wc.numpy()
    guess = _shifted(truth, -np.asarray(offset))
    cfg = RelocalizeCfg(search_xy_m=1.0)
    scan = scan_xy_m(frame.depth_m.numpy(), frame.intrinsics.numpy(), guess, cfg)
    m = match_scan(world.occupancy, scan, guess[:2, 3], cfg)
    assert m.confident, m.reason
    found = apply_correction(m.correction, guess[:2, 3], np.array([*guess[:2, 3], 0.0]))
    assert np.linalg.norm(found[:2] - truth[:2, 3]) < 0.06
    assert abs(m.correction[2] - offset[2]) < math.radians(1.5)


def test_a_bare_wall_is_ambiguous(apt):
    m = _match_from(apt, FACING_WALL)
    assert not m.confident and m.reason == "ambiguous"


def _match_from(apt, pose_xyyaw):
    """The scan match of the head camera's depth seen from ``pose_xyyaw``, started at the true pose."""
    world = _world(apt, pose_xyyaw)
    frame = world.capture()
    world.close()
    pose = frame.pose_wc.numpy()
    cfg = RelocalizeCfg()
    return match_scan(world.occupancy, scan_xy_m(frame.depth_m.numpy(), frame.intrinsics.numpy(), pose, cfg),
                      pose[:2, 3], cfg)


class _SlippedOdometry:
    """A stand-in for ``RgbdOdometry``: the true camera pose on the first frame, then TRACKING
    poses moved by ``slip`` (a VO whose frame slipped: a wrong relocalisation)."""

    def __init__(self, world, slip):
        self.world, self.slip, self.index = world, np.asarray(slip, float), -1

    def track(self, rgb, depth, gyro=None, motion_cam=None):
        self.index += 1
        pose = self.world.camera_pose_wc()
        if self.index > 0:
            pose = _shifted(pose, self.slip)
        return VoResult(pose_wc=pose, state=TrackState.TRACKING, inliers=200, num_keyframes=1, tracked=True)


def _localizer(world, with_map: bool, slip=(0.6, -0.4, 0.0), **kw):
    loc = LegVoLocalizer(odometry=_SlippedOdometry(world, slip),
                         map_source=(lambda: world.occupancy) if with_map else None, **kw)
    loc.reset(world)
    return loc


def test_a_slipped_vo_is_moved_back_by_the_map_and_its_later_fixes_agree(apt):
    world = _world(apt, FACING_ROOM)
    truth = world.true_pose()
    loc = _localizer(world, with_map=True)
    frames = [world.capture() for _ in range(3)]
    first, slipped, later = (loc.on_frame(f) for f in frames)
    world.close()
    assert first.source == "vo"
    assert slipped.tracked and slipped.source == "map" and loc.map_checks[-1][2] == "legs"
    assert np.linalg.norm(slipped.xyyaw[:2] - truth[:2]) < 0.06
    assert np.linalg.norm(slipped.pose_wc[:2, 3] - frames[1].pose_wc.numpy()[:2, 3]) < 0.06
    assert later.tracked and later.source == "vo" and loc.rejected == 0
    assert np.linalg.norm(later.xyyaw[:2] - truth[:2]) < 0.06


def test_without_a_map_the_slipped_vo_is_refused_within_the_bridge(apt):
    world = _world(apt, FACING_ROOM)
    loc = _localizer(world, with_map=False)
    loc.on_frame(world.capture())
    est = loc.on_frame(world.capture())
    world.close()
    assert not est.tracked and est.state == "rejected" and loc.rejected == 1


ALONG_WALL, OFF_WALL = (0.6, 0.0, 0.0), (0.1, -0.4, 0.0)
"""VO slips facing the north wall (along x): along it the map cannot tell the VO from the legs;
0.4 m back from it the VO's pose puts the wall into space the map saw free."""


@pytest.mark.parametrize("pose, slip, with_map, taken", [
    (FACING_WALL, ALONG_WALL, True, False), (FACING_WALL, OFF_WALL, True, True), (FACING_ROOM, (0.6, -0.4, 0.0), True, True),
    (FACING_WALL, ALONG_WALL, False, True)])
def test_past_the_bridge_a_disagreeing_fix_is_taken_only_where_the_map_confirms_it(apt, pose, slip, with_map, taken):
    world = _world(apt, pose)
    truth = world.true_pose()
    loc = _localizer(world, with_map, slip, bridge_max_m=-1.0)  # every bridge has run out
    loc.on_frame(world.capture())
    est = loc.on_frame(world.capture())
    world.close()
    assert est.tracked == taken
    if not taken:
        assert est.state == "unverified" and est.source == "none" and loc.unverified == 1
    elif with_map:
        assert np.linalg.norm(est.xyyaw[:2] - truth[:2]) < 0.06  # at the map's pose, not the VO's
    else:
        assert np.linalg.norm(est.xyyaw[:2] - truth[:2]) > 0.5  # no witness: the VO's (module docstring)


def test_a_robot_facing_a_bare_wall_is_told_to_look_where_a_match_is_confident(apt):
    x, y, _ = FACING_WALL
    look = look_yaw_rad(apt.occupancy, (x, y), RelocalizeCfg())
    assert look is not None and abs(math.remainder(look - FACING_WALL[2], 2 * math.pi)) > math.radians(60)
    m = _match_from(apt, (x, y, look))
    assert m.confident, m.reason


def _level_camera(height_m):
    """(4, 4) a camera at (0, 0, height_m) looking along world +x (OpenCV axes: z forward, y down)."""
    pose = np.eye(4)
    pose[:3, :3] = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]
    pose[2, 3] = height_m
    return pose


def test_a_wall_is_in_the_scan_and_a_table_top_is_not():
    k = np.array([[100.0, 0, 40], [0, 100.0, 30], [0, 0, 1]])
    v = np.arange(60, dtype=float)[:, None].repeat(80, 1)
    wall = np.full((60, 80), 2.0)  # a wall 2 m ahead: depth 2 everywhere
    below = (v - 30) / 100  # the rays' downward slope
    top = np.where(below > 0.01, 0.6 / np.maximum(below, 1e-9), 0.0)  # a level top 0.6 m under the camera
    cfg = RelocalizeCfg(pixel_stride=2)
    pose = _level_camera(1.2)
    wall_xy = scan_xy_m(wall.astype(np.float32), k, pose, cfg)
    assert len(wall_xy) > 300 and np.allclose(wall_xy[:, 0], 2.0, atol=1e-6)
    top = np.where(top <= cfg.max_depth_m, top, 0.0).astype(np.float32)
    assert len(scan_xy_m(top, k, pose, cfg)) == 0
    assert len(scan_xy_m(top, k, pose, RelocalizeCfg(pixel_stride=2, max_normal_z=1.01))) > 100


class _LostOdometry:
    """A stand-in for ``RgbdOdometry``: the true pose on the first frame, then LOST (coasted 1 m off)."""

    def __init__(self, world):
        self.world, self.index = world, -1

    def track(self, rgb, depth, gyro=None, motion_cam=None):
        self.index += 1
        pose = self.world.camera_pose_wc()
        if self.index == 0:
            return VoResult(pose_wc=pose, state=TrackState.TRACKING, inliers=200, num_keyframes=1, tracked=True)
        return VoResult(pose_wc=_shifted(pose, (1.0, 0.0, 0.0)), state=TrackState.LOST, inliers=0, num_keyframes=1,
                        tracked=False)


@pytest.mark.parametrize("with_map", [True, False])
def test_with_the_vo_lost_past_the_bridge_a_drifted_legs_pose_is_pulled_back_onto_the_map(apt, with_map):
    world = _world(apt, FACING_ROOM)
    truth = world.true_pose()
    loc = LegVoLocalizer(odometry=_LostOdometry(world), map_source=(lambda: world.occupancy) if with_map else None,
                         bridge_max_m=-1.0)
    loc.reset(world)
    loc.on_frame(world.capture())
    drifted = truth + np.array([0.3, -0.2, math.radians(3)])  # where a long bridge left the estimate
    loc._anchor(drifted, world.time_s)
    est = loc.on_frame(world.capture())
    world.close()
    if with_map:
        assert est.tracked and est.source == "map" and loc.map_checks[-1][:2] == (est.time_s, "vo lost")
        assert np.linalg.norm(est.xyyaw[:2] - truth[:2]) < 0.06
        assert np.linalg.norm(loc.pose()[:2] - truth[:2]) < 0.06
    else:
        assert not est.tracked and np.linalg.norm(est.xyyaw[:2] - drifted[:2]) < 0.01
