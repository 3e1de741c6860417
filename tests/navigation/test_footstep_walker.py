"""The learned footstep walker (``navigation.footstep_walker``): it feeds the shipped
humanoid-footsteps policy what the training env feeds it, and walks footstep plans onto their
footholds on the CPU engine (straight, from the footstep planner, in an estimate frame that is not
the simulator's), stops when told, and takes the navigator to a goal."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from ambulo.nav import FootstepPlan, FootstepPlanner, GridMap, PlanStatus
from ambulo.navigation import Navigator, NavigatorCfg, NavWorld, NavWorldCfg, Walker
from ambulo.navigation.benchmark import make_walker
from ambulo.navigation.footstep_walker import FootstepPolicyWalker, FootstepWalkerCfg

pytest.importorskip("onnxruntime")

START = (-1.0, 0.0, 0.0)
"""The robot's start in the test room (``conftest.ROOM_XML``): 2.5 m of free floor ahead along +x."""


def _plan(rows, sides) -> FootstepPlan:
    rows = np.asarray(rows, float)
    return FootstepPlan(status=PlanStatus.SUCCESS, footsteps_xyyaw_w=rows, foot_sides=np.asarray(sides, np.int8),
                        foot_z_m=np.zeros(len(rows)), cost=0.0, expansions=0, planning_time_s=0.0)


def _straight_plan(feet_xyyaw, num_steps: int, step_m: float = 0.15, width_m: float = 0.18) -> FootstepPlan:
    """From the (2, 3) left and right ``feet_xyyaw`` (the left moves first), ``num_steps`` steps
    along the left foot's heading, each foot ``step_m`` ahead of the other, ``width_m`` apart."""
    left, right = np.asarray(feet_xyyaw, float)
    yaw = float(left[2])
    fwd, lat = np.array([math.cos(yaw), math.sin(yaw)]), np.array([-math.sin(yaw), math.cos(yaw)])
    mid = 0.5 * (left[:2] + right[:2])
    rows, sides = [left, right], [1, -1]
    for i in range(1, num_steps + 1):
        side = sides[-2]
        xy = mid + i * step_m * fwd + side * 0.5 * width_m * lat
        rows.append([xy[0], xy[1], yaw])
        sides.append(side)
    return _plan(rows, sides)


def _run(world, walker, seconds: float, estimate=lambda pose: pose) -> None:
    """Step ``walker`` and ``world`` for ``seconds``, the walker given ``estimate(true pose)``."""
    for _ in range(int(round(seconds / world.dt_s))):
        walker.step(world.dt_s, estimate(world.true_pose()))
        world.step()
        if world.fell:
            return


def _end_body_xy(plan: FootstepPlan) -> np.ndarray:
    return plan.footsteps_xyyaw_w[-2:, :2].mean(axis=0)


# -- the observation and the plan, step by step against the training env ------------------------
def test_the_walker_feeds_the_policy_what_the_training_env_feeds_it():
    """One humanoid-footsteps world (CPU) follows a 10-step plan (``follow_plans``) driven by the
    shipped policy; alongside, the walker reads the same robot (its contacts and soles from the
    simulator, its plan advanced by its own touchdowns): at every policy step its observation is
    the env's, value for value, while both targets are the plan's (then the env draws more, the
    walker holds), and it counts the plan's touchdowns as the env does."""
    from ambulo import envs
    from ambulo.policies import load_policy

    env = envs.make("humanoid-footsteps", num_envs=1, device="cpu", play=True, seed=0)
    assert env.transfer.action_delay is None  # the env steps its physics in one call per policy step
    env.reset()

    def true_pose():
        return env._base_xyyaw_w()[0].double().numpy()

    world = SimpleNamespace(model=env.engine.model, engine=env.engine, robot=env.robot,
                            dt_s=env.physics_dt_s, start_pose=tuple(true_pose()), true_pose=true_pose, time_s=0.0)
    walker = FootstepPolicyWalker()
    walker.bind(world)
    walker.reset()  # the default pose, standing; the env's observation is recomputed below
    walker._pose = true_pose()
    feet = walker.soles_xyyaw()
    plan = _straight_plan(feet, 10)
    obs = env.follow_plans(torch.tensor(plan.footsteps_xyyaw_w[None], dtype=torch.float32),
                           torch.tensor(plan.foot_sides[None].astype(np.float32)), torch.tensor([plan.num_steps]))
    walker.set_plan(plan, final=True)

    decimation = env.cfg.decimation

    def sim_step(num_substeps, refresh=False):  # the env's physics, the walker reading its feet before the last
        diverged = env.engine.step(num_substeps - 1)
        walker._read_feet()
        diverged = diverged | env.engine.step(1)
        env.sim.update(num_substeps * env.physics_dt_s)
        return diverged

    env.sim.step = sim_step
    policy = load_policy("humanoid-footsteps")
    compared = 0
    for _ in range(150):
        walker._pose = true_pose()
        walker._control()
        taken = int(env.steps_taken[0])
        if taken >= plan.num_steps:
            break
        if taken <= plan.num_steps - 2:  # both targets still the plan's (then the env draws the next)
            assert not walker.standing
            mine = walker.policy.observation(walker.command)
            assert torch.equal(walker.state.targets_xyyaw_w, env.targets_xyyaw_w)
            torch.testing.assert_close(walker.state.since_advance_s, env.since_advance_s)
            torch.testing.assert_close(mine, obs, atol=1e-5, rtol=0)
            compared += 1
        obs = env.step(policy(obs))[0]
        walker.policy.actions = env.actions.clone().float()
        world.time_s += decimation * env.physics_dt_s
    assert int(env.steps_taken[0]) == plan.num_steps and not bool(env._fell[0])
    assert len(walker.touchdowns) == plan.num_steps
    assert compared > 60, compared


def test_the_walker_reads_the_feet_where_the_env_does(room):
    """The env's contact sensor and sole sites are MuJoCo's from before a policy step's last physics
    step; the walker reads the feet there too (the parity test above reads them in the env's
    physics, so this pins where ``step`` does it): before physics steps 3, 7, 11 of 4-step periods."""
    world = NavWorld.from_file(room, start_pose=START, cfg=NavWorldCfg(record_gyro=False))
    walker = FootstepPolicyWalker()
    walker.bind(world)
    walker.reset()
    steps, physics = [], [0]
    walker._read_feet = lambda: steps.append(physics[0])
    for _ in range(12):
        walker.step(world.dt_s, world.true_pose())
        world.step()
        physics[0] += 1
    assert walker._decimation == 4 and steps == [3, 7, 11]
    world.close()


# -- walking plans in a NavWorld ------------------------------------------------------------------
def _rigid(offset_xyyaw):
    """The pose estimate of a frame ``offset_xyyaw`` (x m, y m, yaw rad) away from the simulator's."""
    ox, oy, oyaw = offset_xyyaw
    c, s = math.cos(oyaw), math.sin(oyaw)

    def estimate(pose):
        return np.array([ox + c * pose[0] - s * pose[1], oy + s * pose[0] + c * pose[1],
                         math.atan2(math.sin(pose[2] + oyaw), math.cos(pose[2] + oyaw))])

    return estimate


@pytest.mark.parametrize("offset", [None, (0.7, -0.4, 0.6)], ids=["oracle", "estimate_frame"])
def test_the_walker_puts_its_feet_on_a_straight_plan(room, offset):
    """8 steps of 0.15 m from where it stands: no fall, every step touched down (median error
    <= 5 cm), standing at the plan's end afterwards. With ``estimate_frame`` the plan and the pose
    are in a frame 0.8 m and 0.6 rad from the simulator's (the navigator's map): the same walk."""
    world = NavWorld.from_file(room, start_pose=START, cfg=NavWorldCfg(record_gyro=False))
    estimate = _rigid(offset) if offset is not None else (lambda pose: pose)
    walker = FootstepPolicyWalker()
    walker.bind(world)
    walker.reset()
    assert isinstance(walker, Walker)
    _run(world, walker, 0.3, estimate)
    feet, _ = walker.start_feet()
    plan = _straight_plan(feet, 8)
    assert walker.refuse(plan) is None
    walker.set_plan(plan, final=True)
    assert walker.remaining_m == pytest.approx(7 * 0.15, abs=0.03)  # the body path from the first step on
    _run(world, walker, 5.0, estimate)
    assert not world.fell
    assert walker.arrived and walker.remaining_m == 0.0
    errors = [e for _, _, e in walker.touchdowns]
    assert len(errors) >= 8
    assert np.median(errors[:8]) <= 0.05, errors
    _run(world, walker, 1.5, estimate)
    end = estimate(world.true_pose())[:2]
    assert np.linalg.norm(end - _end_body_xy(plan)) < 0.1, (end, _end_body_xy(plan))
    assert world.base_speed_m_s() < 0.15 and not world.fell
    world.close()


def test_the_walker_walks_a_planner_plan_to_a_goal_2m_away(room):
    """The footstep planner's plan on an empty map from the walker's own feet (``start_feet``) to
    a goal 2 m away, turned 90 degrees left: walked with every footstep within reach (median
    <= 5 cm, none over 10 cm), ending within 0.1 m of the plan's end, facing its heading."""
    world = NavWorld.from_file(room, start_pose=START, cfg=NavWorldCfg(record_gyro=False))
    walker = FootstepPolicyWalker()
    walker.bind(world)
    walker.reset()
    _run(world, walker, 0.3)
    grid = GridMap.empty((8.0, 8.0), resolution_m=0.05, origin_xy_m=(-4.0, -4.0))
    feet, stance = walker.start_feet()
    goal = (0.6, 1.2, math.pi / 2)
    assert math.hypot(goal[0] - START[0], goal[1] - START[1]) == pytest.approx(2.0)
    plan = FootstepPlanner(grid).plan(goal_xyyaw_w=goal, start_feet_xyyaw_w=feet, stance_side=stance)
    assert plan.status is PlanStatus.SUCCESS and walker.refuse(plan) is None
    walker.set_plan(plan, final=True)
    _run(world, walker, 7.0)
    assert not world.fell and walker.arrived
    errors = [e for _, _, e in walker.touchdowns[:plan.num_steps]]
    assert len(errors) == plan.num_steps
    assert np.median(errors) <= 0.05 and max(errors) <= 0.1, errors
    pose = world.true_pose()
    assert np.linalg.norm(pose[:2] - _end_body_xy(plan)) < 0.1
    assert abs(math.remainder(pose[2] - goal[2], math.tau)) < 0.2
    world.close()


def test_told_to_stand_mid_plan_it_stops_and_holds(room):
    """``stand()`` one second into a 12-step plan: the robot stops short of the plan's end, on the
    footholds it was stepping to (the velocity policy's position hold), and stays there."""
    world = NavWorld.from_file(room, start_pose=START, cfg=NavWorldCfg(record_gyro=False))
    walker = FootstepPolicyWalker()
    walker.bind(world)
    walker.reset()
    _run(world, walker, 0.3)
    plan = _straight_plan(walker.start_feet()[0], 12)
    walker.set_plan(plan, final=True)
    _run(world, walker, 1.0)
    walker.stand()
    _run(world, walker, 2.5)
    assert walker.standing and not walker.arrived
    held = world.true_pose()[:2].copy()
    assert np.linalg.norm(held - walker.hold.hold_xyyaw[:2]) < 0.08
    drift = []
    for _ in range(20):
        _run(world, walker, 0.1)
        drift.append(float(np.linalg.norm(world.true_pose()[:2] - held)))
    assert not world.fell
    assert max(drift) < 0.08, drift
    assert world.true_pose()[0] < _end_body_xy(plan)[0] - 0.5  # it did not walk on
    world.close()


def test_the_navigator_reaches_a_goal_with_the_footstep_walker(room):
    """``make_walker("footsteps")`` behind the navigator (oracle mode) in the test room: 4 m east
    past the crate and the post, arrived, touching nothing, feet on the planned footholds."""
    walker = make_walker("footsteps")
    assert isinstance(walker, FootstepPolicyWalker) and walker.name == "footsteps"
    world = NavWorld.from_file(room, start_pose=(-1.0, 0.0, 0.3), cfg=NavWorldCfg(record_gyro=False))
    nav = Navigator(world, NavigatorCfg(mode="oracle", time_limit_s=40.0), walker=walker)
    nav.set_goal((3.0, 0.2))
    assert nav.run() == "arrived"
    assert not world.fell and world.collisions == []
    assert np.linalg.norm(world.true_pose()[:2] - np.array([3.0, 0.2])) < 0.3
    errors = [e for _, _, e in walker.touchdowns]
    assert len(errors) >= 10 and np.median(errors) <= 0.05
    world.close()


# -- the arms' swing ------------------------------------------------------------------------------
@pytest.mark.parametrize("arm_swing_scale, touches", [(None, False), (1.0, True)], ids=["default", "as_trained"])
def test_walking_0_57m_from_a_wall_its_arms_stay_off_it(room, arm_swing_scale, touches):
    """8 steps of 0.15 m along the room's north wall (its face 0.57 m to the left of the body path):
    with the walker's default ``arm_swing_scale`` nothing touches the wall; with the arms as the
    policy swings them (1.0: a forearm reaches 0.60-0.63 m to the side) a forearm meets it, so the
    distance tests the swing."""
    wall_face_y_m = 1.95  # conftest.ROOM_XML: wall_north at y = 2.0, 0.05 m half thick
    # the start stance's soles are centred ~2 cm right of the pelvis: the body path 0.57 m from the wall
    world = NavWorld.from_file(room, start_pose=(-1.0, wall_face_y_m - 0.55, 0.0), cfg=NavWorldCfg(record_gyro=False))
    cfg = FootstepWalkerCfg() if arm_swing_scale is None else FootstepWalkerCfg(arm_swing_scale=arm_swing_scale)
    walker = FootstepPolicyWalker(cfg)
    walker.bind(world)
    walker.reset()
    _run(world, walker, 0.3)
    plan = _straight_plan(walker.start_feet()[0], 8)
    assert wall_face_y_m - _end_body_xy(plan)[1] == pytest.approx(0.57, abs=0.02)
    walker.set_plan(plan, final=True)
    _run(world, walker, 4.0)
    assert not world.fell and walker.arrived
    walls = [body for _, body in world.collisions if "wall" in body]
    assert bool(walls) is touches, world.collisions
    world.close()


def test_a_negative_arm_swing_scale_is_refused_in_one_line():
    from ambulo.navigation.footstep_walker import FootstepWalkerCfg

    with pytest.raises(Exception, match="arm_swing_scale") as err:
        FootstepWalkerCfg(arm_swing_scale=-0.5)
    assert "\n" not in str(err.value)
