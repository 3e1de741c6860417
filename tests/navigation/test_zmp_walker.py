"""The ZMP walker behind the navigator's Walker interface: it plans from its own feet and refuses a
step it cannot make before taking it."""

import numpy as np

from ambulo.nav import FootstepPlan, PlanStatus
from ambulo.navigation import NavWorld, NavWorldCfg, Walker
from ambulo.navigation.zmp_walker import ZmpWalker


def _plan(rows, sides):
    rows = np.asarray(rows, float)
    return FootstepPlan(status=PlanStatus.SUCCESS, footsteps_xyyaw_w=rows, foot_sides=np.asarray(sides, np.int8),
                        foot_z_m=np.zeros(len(rows)), cost=0.0, expansions=0, planning_time_s=0.0)


def test_zmp_walker_is_a_walker_and_refuses_an_impossible_step(room):
    world = NavWorld.from_file(room, start_pose=(0.0, 0.0, 0.0), cfg=NavWorldCfg(record_gyro=False))
    walker = ZmpWalker()
    walker.bind(world)
    walker.reset()
    assert isinstance(walker, Walker)
    feet, stance = walker.start_feet()
    assert feet.shape == (2, 3) and stance in (-1, 1)
    assert abs(feet[0, 1] - feet[1, 1]) > 0.1  # left and right, side by side
    left, right = feet
    first = right if stance == 1 else left  # the foot that moves first
    side = -stance
    ok = _plan([first, left if stance == 1 else right, first + [0.2, 0.0, 0.0]],
               [side, stance, side])
    assert walker.refuse(ok) is None
    # the same step 0.5 m to the side: beyond the walker's step width, refused with the reason
    wide = _plan([first, left if stance == 1 else right, first + [0.0, 0.5 * side, 0.0]], [side, stance, side])
    reason = walker.refuse(wide)
    assert reason is not None and "width" in reason
    world.close()


def test_a_zmp_walker_whose_feet_lack_room_steps_out_first(room):
    """Started 0.22 m from the north wall's face (the benchmark's starts come within 0.23 m), the
    walker's own feet lack the planner's body clearance: the navigator plans a step out to room
    (``step_out_clearance_m``), not the goal's plan, instead of refusing every plan (stuck)."""
    from ambulo.navigation import Navigator, NavigatorCfg

    world = NavWorld.from_file(room, start_pose=(-1.0, 1.95 - 0.22, 0.0), cfg=NavWorldCfg(record_gyro=False))
    nav = Navigator(world, NavigatorCfg(mode="oracle"), walker=ZmpWalker())
    nav.set_goal((-1.0, -0.5))
    nav._replan(world.time_s, world.true_pose(), "test")
    record = nav.replans[-1]
    assert record.footstep_status == "success" and record.refused is None, record
    assert not nav.plan_final  # a step out, not the goal's plan
    end = nav.plan.footsteps_xyyaw_w[-2:, :2].mean(axis=0)
    assert end[1] < 1.95 - 0.22 - 0.01  # away from the wall
    world.close()
