"""A user world's ground-truth map reaches the start, the goal and the floor: a start and goal far
outside the objects' bounding box still have a route, and off a finite floor plane nothing is free."""

import mujoco
import numpy as np
import pytest

from ambulo.core import GroundCfg, add_ground
from ambulo.navigation import NavWorld, NavWorldCfg
from ambulo.navigation.ground_truth import world_occupancy
from ambulo.navigation.planning import PlanningCfg, RoutePlanner

FEW_OBJECTS_XML = """
<mujoco model="few_objects">
  <worldbody>
    <geom name="floor" type="plane" size="{floor}"/>
    <body name="crate" pos="0.0 0.0 0.3"><geom type="box" size="0.3 0.3 0.3"/></body>
    <body name="post" pos="1.0 0.5 0.5"><geom type="cylinder" size="0.1 0.5"/></body>
  </worldbody>
</mujoco>
"""
"""Two objects within 1.5 m of the origin on a plane (``floor``: MuJoCo's size, 0 = infinite)."""


def _world(tmp_path, floor: str, start, goal) -> NavWorld:
    path = tmp_path / "few_objects.xml"
    path.write_text(FEW_OBJECTS_XML.format(floor=floor))
    return NavWorld.from_file(path, start_pose=start, cfg=NavWorldCfg(record_gyro=False), cover_xy_m=[goal])


def _occupancy(spec: mujoco.MjSpec, points):
    """The ground truth of a world without the robot (what ``NavWorld`` rasterizes, minus its geoms)."""
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return world_occupancy(model, data, include_xy_m=np.asarray(points, float))


def _free(grid, xy) -> bool:
    x0, y0, x1, y1 = grid.extent_xy_m()
    return x0 <= xy[0] < x1 and y0 <= xy[1] < y1 and not grid.occupied()[grid.cell_of(xy)]


@pytest.mark.parametrize("floor", ["0 0 0.1", "20 20 0.1"])
def test_start_and_goal_far_outside_the_objects_have_a_route(tmp_path, floor):
    """Start 4 m west of the crate, goal 5 m east and 3 m north of it: both are inside the map with
    at least 1 m around them, and the route planner joins them."""
    start, goal = (-4.0, -0.5, 0.0), (5.0, 3.0)
    world = _world(tmp_path, floor, start, goal)
    grid = world.occupancy
    x0, y0, x1, y1 = grid.extent_xy_m()
    for x, y in (start[:2], goal):
        assert x0 + 1.0 <= x <= x1 - 1.0 and y0 + 1.0 <= y <= y1 - 1.0, (grid.extent_xy_m(), x, y)
    route = RoutePlanner(PlanningCfg()).route(grid, 0, start[:2], goal)
    assert route.found
    assert np.linalg.norm(route.path_xy_m[-1] - goal) < 1e-9
    assert occupied_at(grid, (0.0, 0.0))  # the crate is still there
    world.close()


def occupied_at(grid, xy) -> bool:
    return bool(grid.occupied()[grid.cell_of(xy)])


def test_a_finite_floor_is_covered_and_nothing_beyond_it_is_free(tmp_path):
    """A 6 m x 4 m floor (half sizes 3, 2): the map covers all of it (the objects' box is 1.6 m
    wide), its cells are free away from the objects, and the cells past its edges are occupied (no
    floor to stand on), so a goal off the floor has no route."""
    grid = _occupancy(mujoco.MjSpec.from_string(FEW_OBJECTS_XML.format(floor="3 2 0.1")), [(-2.0, -1.0), (2.5, 1.5)])
    x0, y0, x1, y1 = grid.extent_xy_m()
    assert x0 <= -3.0 and x1 >= 3.0 and y0 <= -2.0 and y1 >= 2.0
    assert _free(grid, (-2.9, 1.9)) and _free(grid, (2.9, -1.9)) and _free(grid, (2.5, 1.5))
    assert occupied_at(grid, (0.0, 0.0))
    # past the floor's edges (inside the map: its margin reaches 1 m beyond the points)
    assert occupied_at(grid, (-3.1, 0.0)) and occupied_at(grid, (3.1, 1.0)) and occupied_at(grid, (0.0, -2.1))
    route = RoutePlanner(PlanningCfg()).route(grid, 0, (-2.0, -1.0), (3.4, 0.0))
    assert not route.found


def test_the_default_ground_of_a_world_without_a_plane_stays_a_bounded_map():
    """No plane: ``NavWorld.from_spec`` adds the scene builder's 100 m ground; the map reaches past the
    object and the points by its 1 m margin and at most 5 m more, not 50 m."""
    spec = mujoco.MjSpec.from_string('<mujoco><worldbody><body pos="0 0 0.3"><geom type="box" size="0.3 0.3 0.3"/>'
                                     "</body></worldbody></mujoco>")
    add_ground(spec, GroundCfg())
    grid = _occupancy(spec, [(-2.0, 0.0), (2.0, 1.0)])
    x0, y0, x1, y1 = grid.extent_xy_m()
    assert -8.1 <= x0 <= -3.0 and 3.0 <= x1 <= 8.1 and -6.4 <= y0 <= -1.0 and 2.0 <= y1 <= 7.1
    assert _free(grid, (2.0, 1.0)) and _free(grid, (-2.0, 0.0)) and occupied_at(grid, (0.0, 0.0))
