"""Plans the walker can walk: the planner's default limits are the walk controller's, and the
humanoid walks a straight 3 m plan and a plan with a 90 degree turn in MuJoCo without a fall."""

import math

import numpy as np
import pytest

from ambulo.locomotion.walk_sim import WalkSimulation, walk_pattern
from ambulo.nav import GridMap, PlanStatus, plan_footsteps
from ambulo.nav.footstep_lattice import relative
from ambulo.robots.humanoid import SOLE_X_M, WALK_STEP_LENGTH_RANGE_M


def default_plan(goal_xyyaw):
    """A plan with the planner's defaults on an empty floor, from the humanoid's initial stance."""
    grid = GridMap.empty((8.0, 8.0), resolution_m=0.05, origin_xy_m=(-2.0, -4.0))
    plan = plan_footsteps(grid, (SOLE_X_M, 0.0, 0.0), goal_xyyaw)
    assert plan.status is PlanStatus.SUCCESS
    rel = relative(plan.footsteps_xyyaw_w[1:-1], plan.footsteps_xyyaw_w[2:])
    assert rel[:, 0].max() <= WALK_STEP_LENGTH_RANGE_M[1] + 1e-9
    return plan


@pytest.mark.slow
@pytest.mark.parametrize("goal", [(SOLE_X_M + 3.0, 0.0, 0.0), (SOLE_X_M + 1.5, 1.5, math.pi / 2)],
                         ids=["straight_3m", "turn_90deg"])
def test_the_humanoid_walks_default_plans_without_a_fall(goal):
    plan = default_plan(goal)
    result = WalkSimulation(walk_pattern(plan)).run(seed=3)
    summary = result.summary()
    assert not summary["fell"], summary["fall_reason"]
    # it arrives where the plan ends (the feet's midpoint, within 0.15 m)
    end = plan.footsteps_xyyaw_w[-2:, :2].mean(axis=0)
    assert np.hypot(*(result.final_body_xyyaw[:2] - end)) < 0.15
