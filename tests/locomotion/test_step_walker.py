"""``ZmpStepWalker``: the ZMP walker stepping on footstep plans online inside a simulation, taking
new plans mid-walk (issue 24, item 2)."""

import math

import numpy as np
import pytest
import torch

from ambulo.core import Entity, PhysicsCfg, Simulation
from ambulo.locomotion import ZmpStepWalker
from ambulo.locomotion.walk_world import start_walk_world
from ambulo.nav import FootstepPlan, FootstepPlanner, GridMap, PlanStatus, humanoid_footstep_cfg
from ambulo.robots import humanoid

DT = 0.005


def make_plan(rows, sides, z=None) -> FootstepPlan:
    rows = np.asarray(rows, float)
    return FootstepPlan(status=PlanStatus.SUCCESS, footsteps_xyyaw_w=rows, foot_sides=np.asarray(sides, np.int8),
                        foot_z_m=np.zeros(len(rows)) if z is None else np.asarray(z, float), cost=0.0,
                        expansions=0, planning_time_s=0.0)


def straight_plan(feet, lengths, first_side=1):
    """Rows 0, 1 the start feet (``first_side`` moves first), then each foot in turn moved to
    ``length`` ahead of the other (along x, yaw 0), keeping its own y."""
    pos = {1: np.array(feet[0], float), -1: np.array(feet[1], float)}
    rows, sides, side = [pos[first_side].copy(), pos[-first_side].copy()], [first_side, -first_side], first_side
    for length in lengths:
        p = pos[side].copy()
        p[0] = pos[-side][0] + length
        pos[side] = p
        rows.append(p.copy())
        sides.append(side)
        side = -side
    return make_plan(rows, sides)


@pytest.fixture()
def arena_walker():
    world = start_walk_world()
    walker = ZmpStepWalker().bind(world.sim, world.robot)
    walker.reset()
    return world.sim, walker


def run(sim, walker, seconds, until=None):
    for _ in range(int(round(seconds / DT))):
        walker.step(DT)
        sim.step()
        if walker.fell or (until is not None and until()):
            return


# --------------------------------------------------------------------------- refusals (no simulation)
FEET = [[0.03, 0.09, 0.0], [0.03, -0.09, 0.0]]


def test_a_plan_within_the_limits_is_accepted():
    assert ZmpStepWalker().refuse(straight_plan(FEET, [0.2, 0.25, 0.25, 0.0])) is None


def test_a_too_long_step_is_refused_before_it_is_taken():
    walker = ZmpStepWalker()
    plan = straight_plan(FEET, [0.2, 0.25, 0.35, 0.0])  # step 3: 0.35 m > 0.25 m
    reason = walker.refuse(plan)
    assert reason is not None and reason.startswith("step 3 ") and "length 0.350 m" in reason
    assert "\n" not in reason


def test_refusals_name_width_turn_height_and_same_foot():
    walker = ZmpStepWalker()
    # the left foot lands 0.05 m beside the right one: too narrow (limit 0.12 m)
    narrow = make_plan([FEET[0], FEET[1], [0.2, -0.04, 0.0]], [1, -1, 1])
    assert "width 0.050 m" in walker.refuse(narrow)
    # a 0.5 rad turn in one step (limit 0.3 rad)
    turn = make_plan([FEET[1], FEET[0], [0.2, -0.09, -0.5]], [-1, 1, -1])
    assert "turn -28.6 deg" in walker.refuse(turn)
    # 0.10 m up (a flat-floor walker: 0.02 m)
    up = make_plan([FEET[1], FEET[0], [0.2, -0.09, 0.0]], [-1, 1, -1], z=[0.0, 0.0, 0.10])
    assert "step up 0.100 m" in walker.refuse(up)
    same = make_plan([FEET[1], FEET[0], [0.2, 0.09, 0.0]], [-1, 1, 1])
    assert "same foot" in walker.refuse(same)
    assert walker.refuse(make_plan([FEET[0], FEET[0]], [1, 1])) is not None


def test_a_refused_plan_is_not_taken_and_the_walker_stays_standing(arena_walker):
    sim, walker = arena_walker
    reason = walker.set_plan(straight_plan(walker.feet_xyyaw_w(), [0.2, 0.40, 0.0]))
    assert reason is not None and walker.last_refusal == reason
    run(sim, walker, 0.5)
    assert walker.done and walker.is_standing and walker.steps_taken == 0 and walker.swing_target_w is None


# --------------------------------------------------------------------------- splicing
def test_a_plan_made_before_the_last_step_continues_after_the_feet_it_shares(arena_walker):
    sim, walker = arena_walker
    (lx, ly, _), (rx, ry, _) = walker.feet_xyyaw_w()
    # planned when the right foot was 0.2 m behind: its step 1 put the right foot where it is now
    stale = make_plan([[rx - 0.2, ry, 0], [lx, ly, 0], [rx, ry, 0], [lx + 0.2, ly, 0], [rx + 0.2, ry, 0]],
                      [-1, 1, -1, 1, -1])
    assert walker.set_plan(stale) is None
    run(sim, walker, 0.3)
    # the next swing is the plan's step 2 (the left foot), not its step 1 again
    assert np.allclose(walker.swing_target_w, [lx + 0.2, ly, 0.0], atol=1e-6)
    assert walker.stance_side == 1 and walker.remaining_steps == 2


def test_a_plan_whose_start_feet_are_off_keeps_the_real_feet(arena_walker):
    sim, walker = arena_walker
    (lx, ly, _), (rx, ry, _) = walker.feet_xyyaw_w()
    off = 0.05  # more than the 4 cm a plan's foot may be off a real one
    plan = make_plan([[rx + off, ry, 0], [lx + off, ly, 0], [rx + off + 0.2, ry, 0], [lx + off + 0.2, ly, 0]],
                     [-1, 1, -1, 1])
    assert walker.set_plan(plan) is None
    run(sim, walker, 1.5)  # the first swing starts after the 1.8 s transfer from standing
    # the real feet stay where they are (not dragged to the plan's); its first step is taken from them
    assert np.allclose(walker.swing_target_w, [rx + off + 0.2, ry, 0.0], atol=1e-6)
    assert np.allclose(walker.feet_xyyaw_w()[:, :2], [[lx, ly], [rx, ry]], atol=0.005)
    # and the foot lands there in the world, 0.25 m ahead of the real left foot
    run(sim, walker, 3.0, until=lambda: walker.steps_taken >= 1)
    assert not walker.fell and walker.steps_taken == 1
    assert np.hypot(*(walker.feet_xyyaw_w()[1, :2] - [rx + off + 0.2, ry])) < 0.02


# --------------------------------------------------------------------------- walking
def test_a_plan_received_mid_swing_does_not_move_the_swinging_foot(arena_walker):
    sim, walker = arena_walker
    feet0 = walker.feet_xyyaw_w()
    walker.set_plan(straight_plan(feet0, [0.2, 0.2, 0.2, 0.2, 0.0], first_side=-1))
    # into the first swing (right foot), halfway
    run(sim, walker, 3.0, until=lambda: walker.swing_target_w is not None
        and walker.feet_xyyaw_w()[1, 0] > feet0[1, 0] + 0.08)
    assert walker.swing_target_w is not None and walker.steps_taken == 0
    target = walker.swing_target_w.copy()
    # a new plan that has the right foot 6 cm further right and then turns left: the right foot
    # is in the air already, so it lands where it was going and the plan's steps follow from there
    left = walker.feet_xyyaw_w()[0]
    elsewhere = target + [0.0, -0.06, 0.0]
    step1 = [target[0] + 0.15, target[1] + 0.18, 0.2]
    step2 = [step1[0] + 0.18 * math.sin(0.2), step1[1] - 0.18 * math.cos(0.2), 0.3]
    turn = make_plan([left, elsewhere, step1, step2], [1, -1, 1, -1])
    assert walker.set_plan(turn) is None
    assert np.allclose(walker.swing_target_w, target)
    run(sim, walker, 2.0, until=lambda: walker.steps_taken >= 1)
    landed = walker.feet_xyyaw_w()[1]
    assert not walker.fell
    assert np.hypot(*(landed[:2] - target[:2])) < 0.02, (landed, target)  # where it was going
    assert abs(landed[2] - target[2]) < 0.03
    # the plan's first step is under way, from the real feet
    assert np.allclose(walker.swing_target_w, step1, atol=0.02)
    # an empty plan mid-walk: it stops after the step in progress, the CoM over its feet
    assert walker.set_plan(None) is None
    run(sim, walker, 6.0, until=lambda: walker.done)
    assert walker.done and walker.is_standing and not walker.fell and walker.steps_taken <= 2
    balance = walker.balance()
    assert balance.capture_margin_m > 0.02 and balance.zmp_margin_m > 0.02


def test_walks_2m_then_turns_90deg_on_a_plan_received_mid_walk(arena_walker):
    sim, walker = arena_walker
    grid = GridMap.empty((8, 8), resolution_m=0.05, origin_xy_m=(-2, -4))
    planner = FootstepPlanner(grid, humanoid_footstep_cfg(goal_tolerance_m=0.05, goal_tolerance_yaw_rad=0.05))
    start = walker.feet_xyyaw_w()
    plan = planner.plan(goal_xyyaw_w=(start[:, 0].mean() + 2.0, 0.0, 0.0), start_feet_xyyaw_w=start, time_budget_s=2.0)
    assert plan.status == PlanStatus.SUCCESS and walker.set_plan(plan) is None
    run(sim, walker, 20.0, until=lambda: walker.steps_taken >= 4 and walker.swing_target_w is not None)
    feet = walker.next_stance_feet_xyyaw_w()
    mid = feet[:, :2].mean(0)
    new = planner.plan(goal_xyyaw_w=(mid[0] + 0.8, mid[1] + 0.8, math.pi / 2), start_feet_xyyaw_w=feet,
                       stance_side=walker.stance_side, time_budget_s=2.0)
    assert new.status == PlanStatus.SUCCESS and walker.set_plan(new) is None
    run(sim, walker, 30.0, until=lambda: walker.done)
    assert walker.done and not walker.fell and walker.is_standing
    end = walker.feet_xyyaw_w()
    last = new.footsteps_xyyaw_w[-2:]  # the final stance, in the order of the sides
    planned = {int(s): p for s, p in zip(new.foot_sides[-2:], last)}
    for i, side in enumerate((1, -1)):
        assert np.hypot(*(end[i, :2] - planned[side][:2])) < 0.10
    assert abs(math.remainder(end[:, 2].mean() - math.pi / 2, 2 * math.pi)) < 0.15
    # stopped standing, the capture point over the support
    assert walker.balance().capture_margin_m > 0.02


@pytest.mark.slow
def test_walks_a_plan_in_an_apartment_among_its_geoms():
    from ambulo import scenes

    ap = scenes.apartment(3)
    sg = ap.sample_start_goal(np.random.default_rng(0), 2.0, 3.0)
    sim = Simulation(ap.build(robot_pose=sg.start_pose), PhysicsCfg(timestep_s=DT))
    engine = sim.start()
    walker = ZmpStepWalker().bind(sim, Entity(engine, humanoid.PRIM_PATH))
    walker.reset()
    start = walker.feet_xyyaw_w()
    assert np.hypot(*(start[:, :2].mean(0) - np.asarray(sg.start_pose[:2]))) < 0.1  # it stood where it was
    goal = (*sg.goal_xy_m, math.atan2(sg.goal_xy_m[1] - sg.start_pose[1], sg.goal_xy_m[0] - sg.start_pose[0]))
    plan = FootstepPlanner(GridMap.from_map(ap.occupancy)).plan(goal_xyyaw_w=goal, start_feet_xyyaw_w=start,
                                                                time_budget_s=2.0)
    assert plan.status == PlanStatus.SUCCESS and walker.set_plan(plan) is None
    run(sim, walker, plan.num_steps * 0.8 + 10.0, until=lambda: walker.done)
    assert walker.done and not walker.fell
    end_mid, goal_mid = walker.feet_xyyaw_w()[:, :2].mean(0), plan.footsteps_xyyaw_w[-2:, :2].mean(0)
    assert np.hypot(*(end_mid - goal_mid)) < 0.10


def test_falling_when_the_capture_point_leaves_the_support(arena_walker):
    sim, walker = arena_walker
    run(sim, walker, 0.2)
    standing = walker.balance()
    assert not standing.falling and standing.capture_margin_m > 0.05
    # the CoM over the soles' middle at rest: the capture point is there too
    assert np.hypot(*(standing.capture_point_xy - walker.feet_xyyaw_w()[:, :2].mean(0))) < 0.02
    # shoved forward at 1 m/s: xi = c + v / omega lies 1 / sqrt(9.81 / 0.80) = 0.29 m ahead of the
    # CoM, 0.29 - 0.11 (half a sole) = 0.18 m beyond the toes
    robot = walker.robot
    robot.write_root_velocity(lin_vel_w=torch.tensor([[1.0, 0.0, 0.0]], dtype=torch.float64))
    shoved = walker.balance()
    assert shoved.falling
    assert shoved.capture_margin_m == pytest.approx(-0.18, abs=0.03)


def test_a_plan_matching_the_feet_within_tolerance_is_not_rechecked_against_them(arena_walker):
    sim, walker = arena_walker
    (lx, ly, _), right = walker.feet_xyyaw_w()
    # the plan has the left foot 0.015 rad off the real one (a match) and turns the full 0.3 rad
    # from its own left row: 0.315 rad from the real left foot, a hair beyond the limit's slack
    left_row = np.array([lx, ly, -0.015])
    c, s = math.cos(left_row[2]), math.sin(left_row[2])
    step = [lx + c * 0.2 + s * 0.18, ly + s * 0.2 - c * 0.18, left_row[2] - 0.3]
    plan = make_plan([right, left_row, step], [-1, 1, -1])
    assert walker.refuse(plan) is None and walker.set_plan(plan) is None
    run(sim, walker, 0.3)
    assert walker.last_refusal is None
    assert np.allclose(walker.swing_target_w, step, atol=1e-6)
