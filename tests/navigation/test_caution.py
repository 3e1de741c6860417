"""The policy walker where its camera has not seen the floor: it walks slowly near the start, feels
a low box with a foot, steps back from it and refuses plans through it; without that caution the
shipped policy falls on the box (the benchmark's falls: a foot on unseen clutter near the start)."""

import math

import mujoco
import numpy as np
import pytest

from ambulo.nav import FootstepPlan, PlanStatus
from ambulo.navigation import NavWorld, NavWorldCfg
from ambulo.navigation.caution import floor_blind_distance_m
from ambulo.navigation.walkers import PolicyWalker, PolicyWalkerCfg

pytest.importorskip("onnxruntime")

BOX_XML = """
<mujoco model="low_box">
  <worldbody>
    <geom name="floor" type="plane" size="6 6 0.1"/>
    <light pos="0 0 3" dir="0 0 -1"/>
    <body name="low_box" pos="1.0 0.0 0.05"><geom type="box" size="0.25 0.16 0.05" rgba="0.5 0.4 0.3 1"/></body>
  </worldbody>
</mujoco>
"""
"""A 10 cm box (the apartments' "low box") 0.75 m ahead of the start: inside the camera's blind zone."""


def _straight_plan(x0: float, x1: float, step_m: float = 0.2) -> FootstepPlan:
    """Footsteps along y = 0 from x0 to x1 (either way), alternating left (+0.1 m) and right."""
    xs = x0 + math.copysign(step_m, x1 - x0) * np.arange(int(abs(x1 - x0) / step_m + 1e-9) + 1)
    sides = np.where(np.arange(len(xs)) % 2 == 0, 1, -1)
    rows = np.stack([xs, 0.1 * sides, np.zeros(len(xs))], 1)
    return FootstepPlan(status=PlanStatus.SUCCESS, footsteps_xyyaw_w=rows, foot_sides=sides.astype(np.int8),
                        foot_z_m=np.zeros(len(xs)), cost=0.0, expansions=0, planning_time_s=0.0)


def _walk_into_the_box(cfg: PolicyWalkerCfg, seconds: float):
    world = NavWorld.from_spec(mujoco.MjSpec.from_string(BOX_XML), (0.0, 0.0, 0.0), NavWorldCfg(record_gyro=False))
    walker = PolicyWalker(cfg)
    walker.bind(world)
    walker.reset()
    world.engine.forward()
    plan = _straight_plan(0.0, 3.0)
    assert walker.refuse(plan) is None
    walker.set_plan(plan, final=True)
    speeds = []
    for _ in range(int(seconds / world.dt_s)):
        walker.step(world.dt_s, world.true_pose())
        world.step()
        speeds.append(walker.command[0])
        if world.fell:
            break
    return world, walker, np.array(speeds)


def test_the_blind_distance_is_where_the_bottom_of_the_image_meets_the_floor():
    world = NavWorld.from_spec(mujoco.MjSpec.from_string(BOX_XML.replace("1.0 0.0 0.05", "4.0 3.0 0.05")),
                               (0.0, 0.0, 0.0), NavWorldCfg(record_gyro=False))
    blind = floor_blind_distance_m(world)
    frame = world.capture()
    k = frame.intrinsics.numpy()
    row = frame.depth_m.shape[0] - 1
    col = int(round(k[0, 2]))
    z = float(frame.depth_m[row, col])
    # the bottom-centre pixel back-projected (pixel centre: row + 0.5 vs the formula's image edge)
    p_c = np.array([(col - k[0, 2]) / k[0, 0] * z, (row + 0.5 - k[1, 2]) / k[1, 1] * z, z, 1.0])
    p_w = frame.pose_wc.numpy() @ p_c
    cam_w = frame.pose_wc.numpy()[:3, 3]
    assert abs(p_w[2]) < 0.01  # it is the floor
    assert math.hypot(*(p_w[:2] - cam_w[:2])) == pytest.approx(blind, abs=0.03)
    assert 1.0 < blind < 2.5  # the head camera, 18 deg down: ~1.6 m
    world.close()


def test_the_walker_feels_a_low_box_steps_back_and_refuses_plans_through_it():
    world, walker, speeds = _walk_into_the_box(PolicyWalkerCfg(), seconds=4.5)
    assert not world.fell
    assert len(walker.felt_xy_m), "the feet never felt the box"
    # felt at the box's near face (x = 0.75 m) or on its top, within its width
    assert ((walker.felt_xy_m[:, 0] > 0.6) & (walker.felt_xy_m[:, 0] < 1.3)).all(), walker.felt_xy_m
    assert (np.abs(walker.felt_xy_m[:, 1]) < 0.25).all(), walker.felt_xy_m
    assert speeds.max() <= walker.cfg.caution.blind_speed_m_s + 1e-9  # slow: the box is in the blind zone
    assert (speeds < 0).any()  # it stepped back
    assert world.true_pose()[0] < 0.75  # and stands short of the box
    reason = walker.refuse(_straight_plan(world.true_pose()[0], 3.0))
    assert reason is not None and "felt" in reason
    x = world.true_pose()[0]
    assert walker.refuse(_straight_plan(x, x - 0.6)) is None  # away from it: walked
    world.close()


def test_without_caution_the_policy_falls_on_the_box():
    world, walker, _ = _walk_into_the_box(PolicyWalkerCfg(caution=None), seconds=5.0)
    assert world.fell
    world.close()


def test_the_speed_cap_holds_in_blind_zones_only():
    """Capped within the blind distance of the start and of a zone the navigator adds; not elsewhere."""
    world = NavWorld.from_spec(mujoco.MjSpec.from_string(BOX_XML.replace("1.0 0.0 0.05", "4.0 3.0 0.05")),
                               (0.0, 0.0, 0.0), NavWorldCfg(record_gyro=False))
    walker = PolicyWalker()
    walker.bind(world)
    walker.reset()
    world.engine.forward()
    walker.step(world.dt_s, world.true_pose())  # the first control period places the start's zone
    cap = walker.cfg.caution.blind_speed_m_s
    blind = floor_blind_distance_m(world)
    walker.set_plan(_straight_plan(0.0, 3.0), final=True)
    near, far = np.array([blind - 0.1, 0.0, 0.0]), np.array([blind + 0.3, 0.0, 0.0])
    assert walker._cautious((0.5, 0.0, 0.2), near) == (cap, 0.0, 0.2)
    assert walker._cautious((0.5, 0.0, 0.2), far) == (0.5, 0.0, 0.2)
    walker.add_blind_zone(far[:2] + [0.5, 0.0])
    assert walker._cautious((0.5, 0.0, 0.2), far) == (cap, 0.0, 0.2)
    world.close()
