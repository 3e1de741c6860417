"""Issue 24: what the walker's feet felt (``PolicyWalker.felt_xy_m``: low clutter the head camera
never showed) reaches the navigator's map as an obstacle, and the navigator replans around it."""

import numpy as np
import pytest

from ambulo.maps import OCCUPIED

pytest.importorskip("onnxruntime")


def test_a_felt_point_becomes_an_occupied_cell_and_a_replan(room_nav):
    nav = room_nav()
    world = nav.world
    nav.set_goal((2.5, 0.0))
    felt = np.array([[-0.4, 0.05]])
    nav.walker.felt_xy_m = felt  # as the walker records a touch (caution.py)
    before = len(nav.replans)
    nav._control_tick()
    assert nav._felt_marked == 1
    assert len(nav.replans) > before and nav.replans[-1].reason.startswith("felt obstacle")
    nav.mapper._last_refresh_s = -np.inf  # the next refresh is due
    nav.mapper.refresh(world.time_s + 1.0)
    iy, ix = nav.mapper.grid.cell_of(felt[0])
    assert nav.mapper.grid.occupancy[iy, ix] == OCCUPIED
    nav._control_tick()  # the same point again adds nothing
    assert nav._felt_marked == 1
