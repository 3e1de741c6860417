"""Issue 24: a robot already facing down its route, with unseen cells beside the route within its
camera's floor blind zone (a door jamb's shadow just past a door), walks on instead of standing
until the stuck window ends."""

import math

import numpy as np
import pytest

from ambulo.maps import FREE, UNKNOWN, Grid2D

pytest.importorskip("onnxruntime")


def test_a_robot_facing_its_route_walks_on_past_an_unseen_shadow(room_nav):
    nav = room_nav()
    world = nav.world
    nav.set_goal((2.5, 0.0))
    # the map as the robot would hold it: all seen free but a patch beside the route 0.2 m to its
    # left, 0.3-0.7 m ahead (unseen: the walk-on stance 0.6 m ahead touches it)
    g = nav.mapper.grid
    occ = np.full(g.shape, FREE, np.int8)
    iy, ix = np.mgrid[0:g.shape[0], 0:g.shape[1]]
    cx, cy = g.cell_center_xy_m(iy, ix)
    occ[(cx > -0.7) & (cx < -0.3) & (cy > 0.2) & (cy < 0.6)] = UNKNOWN
    nav.mapper.grid = Grid2D(occupancy=occ, origin_xy_m=g.origin_xy_m, resolution_m=g.resolution_m)
    nav.mapper.refresh = lambda time_s, xy=None: False  # keep this map (no frame is fused here)
    zones = len(nav.walker.blind_zones_xy_m)
    nav._replan(world.time_s, np.array([-1.0, 0.0, 0.0]), "test")
    record = nav.replans[-1]
    assert "(faced: walk on)" in record.reason  # the look turn had no step: it faces the route
    assert record.footstep_status == "success" and record.refused is None, record
    assert nav.plan is not None and nav.plan.num_steps >= 2 and not nav.plan_final
    end = nav.plan.footsteps_xyyaw_w[-2:, :2].mean(axis=0)
    assert end[0] > -0.6 and abs(end[1]) < 0.15  # it walks down the route, ~0.6 m
    assert abs(math.atan2(end[1] + 1e-9, end[0] + 1.0)) < 0.3
    # the walk-on counts unseen floor free: the walker goes slowly from here (a blind zone)
    assert len(nav.walker.blind_zones_xy_m) == zones + 1
    assert np.allclose(nav.walker.blind_zones_xy_m[-1], [-1.0, 0.0])
