"""Issue 24: room for the arms before a turn on the spot (``NavigatorCfg.arm_reach_m``). The footstep
planner tests the turned soles and the body's 0.25 m, the forearms reach 0.30-0.33 m in a turn: a robot
by a seen wall first moves, standing, to where the wall is ``arm_reach_m`` away (full mode apartments 3
and 8: forearms on walls the map held, in look turns and a cornered walk-on)."""

import math

import numpy as np
import pytest

from ambulo.maps import FREE, OCCUPIED, UNKNOWN, Grid2D
from ambulo.navigation import Navigator, NavigatorCfg, NavWorld, NavWorldCfg

pytest.importorskip("onnxruntime")


def _wall_map(cx, cy, wall_y_m: float = 0.28):
    """Seen free floor up to x = -0.6 m (unseen beyond: the route ahead), a seen wall for y > ``wall_y_m``."""
    out = np.where(cx > -0.6, UNKNOWN, FREE)
    return np.where(cy > wall_y_m, OCCUPIED, out)


def _navigator(room, fix_map, occ_of, start_pose, **navigator_kw):
    world = NavWorld.from_file(room, start_pose=start_pose,
                               cfg=NavWorldCfg(camera_width=64, camera_height=48, record_gyro=False))
    nav = Navigator(world, NavigatorCfg(mode="mapping", **navigator_kw))
    nav.set_goal((2.5, 0.0))
    fix_map(nav, occ_of)
    return world, nav


def test_a_look_turn_by_a_wall_first_moves_to_arm_room(room, fix_map):
    # facing away from the goal (a look turn is due), the wall's cells 0.25 m from the robot's, edge to edge
    start = np.array([-1.0, 0.0, math.pi])
    world, nav = _navigator(room, fix_map, _wall_map, tuple(start))
    nav._replan(world.time_s, start, "test")
    record = nav.replans[-1]
    assert record.reason == "test (look) (arm room)", record
    assert not nav._look_by_heading and nav.walker.tracker.path is None  # no turn yet: it stands...
    target = nav._arm_back_off[0]
    hold = nav.walker.hold.hold_xyyaw
    np.testing.assert_allclose(hold[:2], target)  # ... and the hold moves it away from the wall
    assert hold[2] == pytest.approx(math.pi)  # at the heading it has
    assert target[1] <= -0.09 and np.linalg.norm(target - start[:2]) <= nav.cfg.arm_shift_m + 1e-9
    # closed loop: the hold takes it there, then it replans and turns to look
    nav.run(until=lambda n: n._arm_back_off is None, max_time_s=nav.cfg.arm_back_off_s + 0.5)
    assert world.true_pose()[1] < -0.05, world.true_pose()  # 5+ cm farther from the wall
    record = nav.replans[-1]
    assert record.reason == "arm room (look)" and nav._look_by_heading, record
    world.close()


def test_arm_room_is_sought_only_where_it_helps(room, fix_map):
    start = np.array([-1.0, 0.0, math.pi])
    world, nav = _navigator(room, fix_map, _wall_map, tuple(start))
    g = nav.mapper.grid
    iy, ix = np.mgrid[0:g.shape[0], 0:g.shape[1]]
    cx, cy = g.cell_center_xy_m(iy, ix)

    def grid(occ):
        return Grid2D(occupancy=occ.astype(np.int8), origin_xy_m=g.origin_xy_m, resolution_m=g.resolution_m)

    assert nav._arm_room_xy(grid(_wall_map(cx, cy)), start) is not None
    # room enough where it stands: no move
    assert nav._arm_room_xy(grid(_wall_map(cx, cy, wall_y_m=0.4)), start) is None
    # a 0.6 m corridor, the robot in its middle: nowhere has more room
    corridor = np.where(np.abs(cy) > 0.3, OCCUPIED, _wall_map(cx, cy, wall_y_m=9.0))
    assert nav._arm_room_xy(grid(corridor), start) is None
    # the room lies behind unseen floor: it moves over free cells only
    unseen = np.where(cy < -0.02, UNKNOWN, _wall_map(cx, cy))
    assert nav._arm_room_xy(grid(unseen), start) is None
    # free floor (the body's disc) but unseen cells 0.2 m behind it: not nearer to them than it stands
    assert nav._arm_room_xy(grid(np.where(cy < -0.2, UNKNOWN, _wall_map(cx, cy))), start) is None
    far = nav._arm_room_xy(grid(np.where(cy < -0.5, UNKNOWN, _wall_map(cx, cy))), start)
    assert far is not None and far[1] <= -0.09  # 0.5 m behind: room to move
    # off (None), or a walker that cannot stand at a point: no move
    nav.cfg.arm_reach_m = None
    assert nav._arm_room_xy(grid(_wall_map(cx, cy)), start) is None
    world.close()


def test_the_first_motion_of_a_goal_moves_to_arm_room_first(room, fix_map):
    # facing the goal down seen free floor (no look turn), a seen wall 0.25 m beside the robot's cell:
    # the goal's first plan moves it away from the wall first; a later plan from there walks
    start = np.array([-1.0, 0.0, 0.0])
    world, nav = _navigator(room, fix_map, lambda cx, cy: np.where(cy > 0.28, OCCUPIED, FREE), tuple(start))
    nav._replan(world.time_s, start, "new goal")
    # (its plan, dropped for the move, may be a roomy one from a cell beside it: roomy_start_shift_m)
    reason = nav.replans[-1].reason
    assert reason.startswith("new goal") and reason.endswith("(arm room)") and nav._arm_back_off is not None, reason
    assert nav._arm_back_off[0][1] <= -0.09
    nav._arm_back_off = None
    nav._replan(world.time_s, start, "period")  # not a turn nor a first motion: it walks from where it is
    reason = nav.replans[-1].reason
    assert reason.startswith("period") and "(arm room)" not in reason and nav.walker.tracker.path is not None, reason
    world.close()


def test_a_plan_the_tracker_starts_by_turning_on_the_spot_moves_to_arm_room_first(room, fix_map):
    # seen free floor all the way (no look turn), the goal behind the robot: the plan's tracker turns on
    # the spot first (apartment 3: a forearm on a door jamb at 9.5 s); by a wall, it moves to arm room
    start = np.array([-1.0, 0.0, math.pi])
    world, nav = _navigator(room, fix_map, lambda cx, cy: np.where(cy > 0.28, OCCUPIED, FREE), tuple(start))
    nav._replan(world.time_s, start, "period")
    reason = nav.replans[-1].reason  # its plan may be a roomy one from a cell beside it (roomy_start_shift_m)
    assert reason.startswith("period") and reason.endswith("(arm room)") and nav._arm_back_off is not None, reason
    # the plan's own start: facing its carrot (the tracker's look-ahead point) it walks at once
    plan = _plan_from(nav, world, start)
    carrot = _carrot(plan, nav.walker.tracker.cfg.lookahead_m)
    facing = math.atan2(carrot[1] - start[1], carrot[0] - start[0])
    assert nav._starts_turning(plan, start)
    assert not nav._starts_turning(plan, np.array([start[0], start[1], facing]))
    assert not nav._starts_turning(plan, np.array([start[0], start[1], facing + 0.6]))  # within 0.75 rad
    world.close()


def _plan_from(nav, world, pose):
    """The footstep plan a replan from ``pose`` makes with arm room off (restored after)."""
    reach, nav.cfg.arm_reach_m = nav.cfg.arm_reach_m, None
    nav._replan(world.time_s, pose, "probe")
    nav.cfg.arm_reach_m = reach
    return nav.plan


def _carrot(plan, lookahead_m):
    from ambulo.navigation.walkers import body_path

    path = body_path(plan)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    return np.array([np.interp(lookahead_m, s, path[:, 0]), np.interp(lookahead_m, s, path[:, 1])])
