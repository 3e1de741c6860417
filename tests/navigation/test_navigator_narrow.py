"""Issue 24: a corridor the online map narrows. Its walls come out up to a cell thicker than they are,
so a passage the ground truth leaves wide enough can lack the route's 0.25 m clearance; the
navigator then routes and plans footsteps with ``narrow_clearance_m`` (0.2 m) instead of standing
with "no_route" until the stuck window ends (full mode apartment 43: 81 such replans)."""

import numpy as np
import pytest

from ambulo.maps import FREE, OCCUPIED, Grid2D
from ambulo.navigation import Navigator, NavigatorCfg, NavWorld, NavWorldCfg

pytest.importorskip("onnxruntime")


@pytest.mark.parametrize("narrow_clearance_m", [0.2, None])
def test_a_corridor_the_map_narrows_is_walked_with_the_narrow_clearance(room, narrow_clearance_m):
    world = NavWorld.from_file(room, start_pose=(-1.0, 0.0, 0.0),
                               cfg=NavWorldCfg(camera_width=64, camera_height=48, record_gyro=False))
    nav = Navigator(world, NavigatorCfg(mode="mapping", narrow_clearance_m=narrow_clearance_m))
    nav.set_goal((1.5, 0.0))
    g = nav.mapper.grid
    iy, ix = np.mgrid[0:g.shape[0], 0:g.shape[1]]
    cx, cy = g.cell_center_xy_m(iy, ix)
    # a corridor 0.45 m wide (cells |y| < 0.225 free) from x = -0.3 m on, everything else seen free
    walls = (cx > -0.3) & (np.abs(cy) > 0.225)
    nav.mapper.grid = Grid2D(occupancy=np.where(walls, OCCUPIED, FREE).astype(np.int8), origin_xy_m=g.origin_xy_m,
                             resolution_m=g.resolution_m)
    nav.mapper.refresh = lambda time_s, xy=None: False  # keep this map
    nav._replan(world.time_s, np.array([-1.0, 0.0, 0.0]), "test")
    record = nav.replans[-1]
    if narrow_clearance_m is None:
        assert record.footstep_status == "no_route", record
    else:
        assert "(narrow)" in record.reason and record.route_found, record
        assert record.footstep_status == "success" and record.refused is None, record
        end = nav.plan.footsteps_xyyaw_w[-2:, :2].mean(axis=0)
        assert end[0] > -0.3  # into the corridor
    world.close()
