"""Issue 24: the navigator's hooks into its parts, end to end on a navigator in the test room: the
map built so far is what the fused localizer relocalises against, and arrival waits for the map
not to contradict the pose (``verify``). (Felt points into the map: test_felt_obstacle_navigator;
blind zones: test_walk_on_unseen.)"""

import numpy as np
import pytest

from ambulo.navigation.localization import OracleLocalizer

pytest.importorskip("onnxruntime")


class ScriptedVerify(OracleLocalizer):
    """The oracle's pose, and ``verify`` answers from a script (what the map check said)."""

    def __init__(self, answers):
        super().__init__()
        self.answers = list(answers)
        self.asked = 0

    def verify(self):
        self.asked += 1
        return self.answers.pop(0)


def _settled_at_goal(nav):
    """The robot stands on its goal and has stood long enough: the next control tick decides."""
    nav.set_goal(nav.world.true_pose()[:2])
    nav._settled_since = nav.world.time_s - 10.0


def test_full_mode_relocalises_against_the_navigators_own_map(room_nav):
    nav = room_nav("full")
    assert nav.localizer.map_source is not None
    assert nav.localizer.map_source() is nav.mapper.grid
    nav.mapper.mark_obstacle((0.5, 0.5))  # a new grid later: the bound source follows the mapper
    nav.mapper._last_refresh_s = -np.inf
    nav.mapper.refresh(nav.world.time_s + 1.0)
    assert nav.localizer.map_source() is nav.mapper.grid


@pytest.mark.parametrize("answers, status", [([False], "walking"), ([None], "arrived"), ([True], "arrived")])
def test_arrival_waits_for_the_map_not_to_contradict_the_pose(room_nav, answers, status):
    nav = room_nav()
    nav.localizer = ScriptedVerify(answers)
    nav.localizer.reset(nav.world)
    _settled_at_goal(nav)
    nav._control_tick()
    assert nav.localizer.asked == 1
    assert nav.status == status
    if status == "walking":  # the map put the robot elsewhere: settle again, and replan from there
        assert nav._settled_since is None and nav._replan_reason == "relocalised"


@pytest.mark.parametrize("answer, status", [(None, "walking"), (True, "arrived")])
def test_no_arrival_while_the_camera_disputes_the_estimate_and_the_map_cannot_tell(room_nav, answer, status):
    """The last camera fix was refused (it disagreed with the legs' bridge the robot walks on): an
    arrival needs the map's confirmation then, not just its silence."""
    nav = room_nav()
    nav.localizer = ScriptedVerify([answer])
    nav.localizer.reset(nav.world)
    _settled_at_goal(nav)
    nav.localizer.needs_images = True  # a camera localizer: the tick keeps the frame's estimate
    nav.estimate.state = "rejected"
    nav._control_tick()
    assert nav.status == status
