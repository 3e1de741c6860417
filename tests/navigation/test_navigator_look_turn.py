"""Issue 24: look turns. The policy walker turns on the spot by its heading alone (its tracker's pure
pursuit of a turn plan's zig-zag body path turned it back and forth for 20 s under randomized
friction and pushes), and a robot that cannot turn on the spot (its turned soles touch a seen
obstacle) walks on down the route instead of refusing look turns until the stuck window ends."""

import math

import numpy as np
import pytest

from ambulo.maps import FREE, OCCUPIED, UNKNOWN
from ambulo.navigation import Navigator, NavigatorCfg, NavWorld, NavWorldCfg

pytest.importorskip("onnxruntime")


def _navigator_on(room, fix_map, occ_of, start_pose, goal_xy, **navigator_kw):
    """A mapping-mode navigator in the test room whose map is ``occ_of(cx, cy)`` (kept fixed)."""
    world = NavWorld.from_file(room, start_pose=start_pose,
                               cfg=NavWorldCfg(camera_width=64, camera_height=48, record_gyro=False))
    nav = Navigator(world, NavigatorCfg(mode="mapping", **navigator_kw))
    nav.set_goal(goal_xy)
    fix_map(nav, occ_of)
    return world, nav


def test_a_look_turn_is_steered_by_the_heading_until_the_robot_faces_the_route(room, fix_map):
    # facing away from the goal; the floor from 0.4 m ahead of the robot (down the route) unseen
    world, nav = _navigator_on(room, fix_map, lambda cx, cy: np.where(cx > -0.6, UNKNOWN, FREE),
                               (-1.0, 0.0, math.pi), (2.5, 0.0))
    nav._replan(world.time_s, np.array([-1.0, 0.0, math.pi]), "test")
    record = nav.replans[-1]
    assert record.reason == "test (look)" and record.footstep_status == "success", record
    assert nav._look_by_heading and abs(nav._look_yaw_rad) < 0.3  # look down the route, along +x
    walker = nav.walker
    assert walker.tracker.path is None  # the turn plan's body path is not followed...
    assert walker._standing and abs(walker._scan_rate) >= 0.3  # ... the walker turns on the spot
    # turning either way is as short from pi to 0; from 2.0 rad the short way is clockwise
    nav._steer_look(np.array([-1.0, 0.0, 2.0]))
    assert walker._scan_rate == pytest.approx(-0.9)
    nav._steer_look(np.array([-1.0, 0.0, 0.2]))
    assert -0.9 < walker._scan_rate <= -0.3  # slower near the heading
    nav._steer_look(np.array([-1.0, 0.0, nav._look_yaw_rad + 0.05]))  # facing it: stand, replan at once
    assert not nav._look_by_heading and walker._scan_rate == 0.0 and nav._replan_reason == "faced"
    nav._replan(world.time_s, np.array([-1.0, 0.0, 0.0]), nav._replan_reason)
    record = nav.replans[-1]
    assert "(faced: walk on)" in record.reason and record.footstep_status == "success", record
    assert walker.tracker.path is not None and not nav._look_by_heading  # it walks down the route
    world.close()


def test_a_robot_that_cannot_turn_on_the_spot_walks_on_down_the_route(room, fix_map):
    # the robot faces along -y, 0.17 m from a seen sideboard before it (its soles clear it); turned
    # to face +x, down the route, its soles would come within a cell of it; the floor from 0.5 m
    # ahead along the route is unseen
    def occ(cx, cy):
        out = np.where(cx > -0.6, UNKNOWN, FREE)
        return np.where((cx > -1.6) & (cx < -0.7) & (cy < 0.08), OCCUPIED, out)

    # (arm_reach_m off: with it the robot first steps back to arm room, test_navigator_arm_room)
    world, nav = _navigator_on(room, fix_map, occ, (-1.1, 0.25, -math.pi / 2), (2.5, 0.6), arm_reach_m=None)
    nav._replan(world.time_s, np.array([-1.1, 0.25, -math.pi / 2]), "test")
    record = nav.replans[-1]
    assert "(cornered: walk on)" in record.reason, record
    assert record.footstep_status == "success" and record.refused is None, record
    assert not nav._look_by_heading and nav.walker.tracker.path is not None
    end = nav.plan.footsteps_xyyaw_w[-2:, :2].mean(axis=0)
    assert np.linalg.norm(end - np.array([-1.1, 0.25])) > 0.3  # it walks on along the route
    world.close()


def test_a_robot_that_looked_here_walks_on_instead_of_looking_again(room, fix_map):
    # apartment 19 (full mode): a walk-on turned the robot off the route's bearing, the next replan
    # turned it back to look, the walk-on turned it away again: 16 s in one place. Looked once
    # here, it walks on, facing where it looked; 0.3 m on, it may look again.
    world, nav = _navigator_on(room, fix_map, lambda cx, cy: np.where(cx > -0.6, UNKNOWN, FREE),
                               (-1.0, 0.0, math.pi), (2.5, 0.0))
    nav._replan(world.time_s, np.array([-1.0, 0.0, math.pi]), "test")
    assert nav._look_by_heading, nav.replans[-1]  # the first look turns
    nav._steer_look(np.array([-1.0, 0.0, 0.0]))  # faced: the turn ends
    turned_away = np.array([-1.0, 0.02, 1.2])  # then something turned it off the route again
    nav._replan(world.time_s, turned_away, "period")
    record = nav.replans[-1]
    assert "(looked: walk on)" in record.reason and record.footstep_status == "success", record
    assert not nav._look_by_heading and nav.walker.tracker.path is not None  # it walks...
    end_yaw = nav.plan.footsteps_xyyaw_w[-2:, 2]
    assert abs(math.atan2(np.sin(end_yaw).sum(), np.cos(end_yaw).sum())) < 0.25  # ... to face down the route
    nav._replan(world.time_s, np.array([-0.65, 0.0, 1.2]), "period")  # 0.35 m on: a look turn again
    assert nav._look_by_heading and "walk on" not in nav.replans[-1].reason, nav.replans[-1]
    world.close()


@pytest.mark.parametrize("look_max_s", [8.0, None])
def test_a_look_turn_that_never_ends_becomes_a_walk_on(room, fix_map, look_max_s):
    # device apartment 93 (full mode): each period replan renewed the look turn with the heading the
    # map then gave, and the robot never faced it: 20 s of look turns at its start. After look_max_s
    # of one turn from the same spot it walks on down the route, as after a look that ended.
    world, nav = _navigator_on(room, fix_map, lambda cx, cy: np.where(cx > -0.6, UNKNOWN, FREE),
                               (-1.0, 0.0, math.pi), (2.5, 0.0), look_max_s=look_max_s)
    t0 = world.time_s
    nav._replan(t0, np.array([-1.0, 0.0, math.pi]), "test")
    assert nav._look_by_heading, nav.replans[-1]  # a look turn begins
    still_turning = np.array([-1.0, 0.02, 2.0])  # it has not faced the route (turned back and forth)
    nav._replan(t0 + 5.0, still_turning, "period")
    assert nav._look_by_heading and "walk on" not in nav.replans[-1].reason, nav.replans[-1]
    nav._replan(t0 + 9.0, still_turning, "period")
    record = nav.replans[-1]
    if look_max_s is None:
        assert nav._look_by_heading and "walk on" not in record.reason, record
    else:
        assert "(long look)" in record.reason and "(looked: walk on)" in record.reason, record
        assert record.footstep_status == "success", record
        assert not nav._look_by_heading and nav.walker.tracker.path is not None  # it walks
    world.close()
