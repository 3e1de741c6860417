"""The humanoid walks planned footsteps in MuJoCo (issue 14, part 4): the whole-body IK, the
inverse-dynamics feed-forward and the simulated walk's balance."""

import math

import mujoco
import numpy as np
import pytest

from ambulo.locomotion.balance import polygon_signed_distance
from ambulo.locomotion.walk_controller import HUMANOID_FOOT, StabilizerCfg, WalkIK, build_reference, walk_robot
from ambulo.locomotion.walk_sim import WalkSimCfg, WalkSimulation, acceptance_walk, walk_pattern
from ambulo.locomotion.walk_world import start_walk_world
from ambulo.robots.humanoid import LEG_JOINTS, SOLE_SITES
from ambulo.robots.humanoid import PRIM_PATH as ROBOT_PRIM_PATH
from ambulo.scenes.walk_arena import GROUND_GEOM, walk_model, walk_physics

GRAVITY = 9.81


@pytest.fixture(scope="module")
def world():
    """The walk arena on the core, the humanoid in its home keyframe."""
    return start_walk_world()


@pytest.fixture(scope="module")
def model(world):
    return world.model


@pytest.fixture(scope="module")
def acceptance():
    """The acceptance walk: 3 m straight, then a 90 deg turn on the spot (planned on an empty map)."""
    return acceptance_walk()


def short_plan(num_steps=4, length=0.2):
    half = 0.09
    plan = [{"x": 0.03, "y": half, "yaw": 0.0, "side": "left"}, {"x": 0.03, "y": -half, "yaw": 0.0, "side": "right"}]
    for i in range(num_steps):
        side = "left" if i % 2 == 0 else "right"
        plan.append({"x": 0.03 + length * min(i + 1, num_steps - 1), "y": half if side == "left" else -half,
                     "yaw": 0.0, "side": side})
    return plan


def test_ik_puts_com_and_soles_where_asked(model, world):
    ik = WalkIK(model)
    q0 = world.home_qpos.copy()
    com = np.array([0.05, 0.03, 0.80])
    feet = np.array([[0.15, 0.10, 0.05, 0.2], [-0.02, -0.09, 0.0, -0.1]])  # left swings up and ahead
    q, err = ik.solve(q0, com, pelvis_yaw=0.05, feet_xyzyaw=feet)
    assert err < 1e-6
    robot = walk_robot(model)
    data = mujoco.MjData(model)  # checked with a fresh forward pass, not the IK's own data
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.subtree_com[robot.root_body_id], com, atol=1e-6)
    for site, foot in zip(("left_sole", "right_sole"), feet):
        np.testing.assert_allclose(data.site_xpos[robot.site_id(site)], foot[:3], atol=1e-6)
        mat = data.site_xmat[robot.site_id(site)].reshape(3, 3)
        assert math.atan2(mat[1, 0], mat[0, 0]) == pytest.approx(foot[3], abs=1e-6)
        assert mat[2, 2] == pytest.approx(1.0, abs=1e-9)  # sole flat
    pelvis = data.xmat[robot.body_id("pelvis")].reshape(3, 3)
    assert pelvis[2, 2] == pytest.approx(1.0, abs=1e-9)
    for j in range(model.njnt):  # a reachable pose within the joint ranges
        if model.jnt_limited[j]:
            lo, hi = model.jnt_range[j]
            assert lo - 1e-9 <= q[model.jnt_qposadr[j]] <= hi + 1e-9


def test_feed_forward_carries_the_weight_and_its_zmp_stays_on_the_soles(model, world):
    pattern = walk_pattern(short_plan())
    ref = build_reference(model, pattern, world.home_qpos)
    weight = float(model.body_subtreemass[walk_robot(model).root_body_id]) * GRAVITY
    # the contact forces of the reference motion carry the robot: m (g + z_ddot), z constant
    np.testing.assert_allclose(ref.contact_wrench[:, :, 2].sum(axis=1), weight, rtol=0.01)
    # standing still, the multi-body ZMP is the cart-table ZMP (the CoM's ground projection)
    np.testing.assert_allclose(ref.zmp_multibody[:100], pattern.zmp_xy[:100], atol=1e-3)
    # while walking it departs from the cart-table ZMP by the swing leg's dynamics, but stays on the soles
    margins = np.array([polygon_signed_distance(ref.zmp_multibody[k], pattern.support_polygon(k))
                        for k in range(len(pattern.time_s))])
    assert margins.min() > 0.02
    assert np.abs(ref.zmp_multibody - pattern.zmp_xy).max() < 0.06
    assert ref.ik_error.max() < 1e-6


def check_acceptance(summary, result):
    assert not summary["fell"], summary["fall_reason"]
    assert summary["zmp_inside_single_support"] >= 0.95
    assert summary["single_support_samples"] > 2000
    assert summary["touchdowns"] == 20 and np.all(result.capture_margin_m > 0.0)
    assert summary["capture_in_stance_sole_at_liftoff"] == summary["liftoffs"]
    assert summary["distance_m"] == pytest.approx(3.0, abs=0.1)
    assert summary["turn_deg"] == pytest.approx(90.0, abs=5.0)


def test_humanoid_walks_3_m_and_turns_90_deg_with_the_zmp_on_its_soles(acceptance):
    plan, sim = acceptance
    assert plan.status.value == "success"
    result = sim.run(seed=0)
    summary = result.summary()
    check_acceptance(summary, result)
    # the walk is balanced with room to spare: the measured ZMP stays 5 mm inside in nearly all of single support
    assert np.percentile(result.single_support_margins_m, 5) > 0.005
    # the CoM ends over the last stance, at the pattern's height
    assert result.com_w[-1, 2] == pytest.approx(sim.pattern.com_pos_w[-1, 2], abs=0.02)


def test_without_the_stabilizer_the_same_walk_falls(acceptance):
    _, sim = acceptance
    open_loop = WalkSimulation(sim.pattern, WalkSimCfg(stabilizer=StabilizerCfg(enabled=False)))
    result = open_loop.run(seed=None)
    assert result.fell


@pytest.mark.slow
def test_ten_seeded_walks_never_fall(acceptance):
    _, sim = acceptance
    for seed in range(10):
        result = sim.run(seed=seed)
        check_acceptance(result.summary(), result)


def test_seeds_perturb_the_start_reproducibly(acceptance):
    _, sim = acceptance
    states = []
    for seed in (3, 3, 4):  # written into the engine's world through the Entity, read back from it
        sim._start(seed)
        states.append(sim.world.engine.get_data(0))
    a, b, c = states
    joints, base = sim.joint_qpos, sim.base_dofs
    np.testing.assert_array_equal(a.qpos, b.qpos)
    np.testing.assert_array_equal(a.qpos, sim.start_state(3)[0])
    np.testing.assert_array_equal(a.qvel, sim.start_state(3)[1])
    assert np.abs(a.qpos[joints] - c.qpos[joints]).max() > 1e-3
    assert np.abs(a.qpos[joints] - sim.reference.qpos[0][joints]).max() <= sim.cfg.joint_noise_rad + 1e-12
    assert 0 < np.linalg.norm(a.qvel[base[:2]]) <= sim.cfg.base_speed_noise_mps
    assert a.time == 0.0 and not a.ctrl.any()  # a fresh start: the reset cleared the last run's time and drives
    # the soles start on the floor, not in it
    feet = [sim.robot.geom_id(name) for name in ("left_foot", "right_foot")]
    lowest = min(a.geom_xpos[g][2] - np.abs(a.geom_xmat[g].reshape(3, 3)[2]) @ sim.model.geom_size[g] for g in feet)
    assert lowest == pytest.approx(0.0, abs=1e-9)


def test_foot_shape_is_the_humanoids_sole(model):
    robot = walk_robot(model)
    size = model.geom_size[robot.geom_id("left_foot")]
    assert (HUMANOID_FOOT.length_m, HUMANOID_FOOT.width_m) == pytest.approx((2 * size[0], 2 * size[1]))
    # the sole site sits at the centre of the sole box's bottom face
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    geom, site = robot.geom_id("left_foot"), robot.site_id("left_sole")
    np.testing.assert_allclose(data.site_xpos[site][:2], data.geom_xpos[geom][:2], atol=1e-9)
    assert data.site_xpos[site][2] == pytest.approx(data.geom_xpos[geom][2] - size[2], abs=1e-9)


def test_map_obstacles_become_boxes_covering_exactly_the_occupied_cells():
    from ambulo.locomotion.walk_sim import grid_obstacles
    from ambulo.nav import GridMap

    occupied = np.zeros((30, 40), bool)
    occupied[5:12, 3:9] = True  # a block
    occupied[20:22, 10:35] = True  # a wall
    occupied[12:20, 30:33] = True  # an L with the wall
    grid = GridMap.from_array(occupied, resolution_m=0.1, origin_xy_m=(-1.0, 2.0))
    boxes = grid_obstacles(grid, 0.4)
    covered = np.zeros_like(occupied, dtype=int)
    centers = grid.cell_centers_xy_m()  # (num_y, num_x, 2)
    for cx, cy, sx, sy, h in boxes:
        assert h == 0.4
        inside = (np.abs(centers[..., 0] - cx) < sx / 2) & (np.abs(centers[..., 1] - cy) < sy / 2)
        covered += inside
    np.testing.assert_array_equal(covered, occupied.astype(int))  # every occupied cell once, no free cell
    assert len(boxes) <= 4
    model = walk_model(obstacles=boxes)
    assert sum(model.geom(i).name.startswith("/World/obstacles/obstacle") for i in range(model.ngeom)) == len(boxes)


def test_ik_agrees_with_mink(model, world):
    """The same targets solved by mink (MuJoCo-based differential IK with a QP, an independent
    implementation) give the same configuration: the task set is square, so the solution is unique."""
    mink = pytest.importorskip("mink")

    q0 = world.home_qpos.copy()
    com, pelvis_yaw = np.array([0.05, 0.03, 0.80]), 0.05
    feet = np.array([[0.15, 0.10, 0.05, 0.2], [-0.02, -0.09, 0.0, -0.1]])
    q_ours, err = WalkIK(model).solve(q0, com, pelvis_yaw, feet)
    assert err < 1e-6

    def se3(pos, yaw):
        return mink.SE3.from_rotation_and_translation(mink.SO3.from_z_radians(yaw), np.asarray(pos, float))

    tasks = []
    # mink's CoM task is the subtree of body 1: walk_model's humanoid is attached first
    assert walk_robot(model).root_body_id == 1
    for name, foot in zip(SOLE_SITES, feet):
        task = mink.FrameTask(f"{ROBOT_PRIM_PATH}/{name}", "site", position_cost=1.0, orientation_cost=1.0)
        task.set_target(se3(foot[:3], foot[3]))
        tasks.append(task)
    pelvis = mink.FrameTask(f"{ROBOT_PRIM_PATH}/pelvis", "body", position_cost=0.0, orientation_cost=1.0)
    pelvis.set_target(se3([0.0, 0.0, 0.0], pelvis_yaw))
    com_task = mink.ComTask(cost=1.0)
    com_task.set_target(com)
    cost = np.full(model.nv, 10.0)  # torso and arms held at home, as in WalkIK
    cost[:6] = 0.0
    legs = walk_robot(model).joint_model_ids([f"{s}_{j}" for s in ("left", "right") for j in LEG_JOINTS])
    cost[model.jnt_dofadr[legs]] = 0.0
    posture = mink.PostureTask(model, cost=cost)
    posture.set_target(q0)
    configuration = mink.Configuration(model, q0)
    for _ in range(300):
        velocity = mink.solve_ik(configuration, [*tasks, pelvis, com_task, posture], 0.05, solver="daqp", damping=1e-6)
        configuration.integrate_inplace(velocity, 0.05)
    np.testing.assert_allclose(configuration.q[:3], q_ours[:3], atol=1e-6)
    np.testing.assert_allclose(configuration.q[7:], q_ours[7:], atol=1e-5)


def test_walk_model_is_built_by_the_core_scene_builder():
    """The humanoid sits at its prim path on the core's ground plane with the physics of one
    ``PhysicsCfg``; the file's ``home`` keyframe is the world's initial state, through the Entity,
    not a key compiled into the model."""
    from ambulo.core import GroundCfg, PhysicsCfg, RobotCfg, add_ground, add_robot, compile_scene, new_scene

    world = start_walk_world(friction=0.7, timestep_s=0.004)
    model = world.model
    robot = walk_robot(model)
    assert model.body(robot.root_body_id).name == f"{ROBOT_PRIM_PATH}/pelvis"
    assert len(robot.joint_names) == 21 and "left_knee" in robot.joint_names
    floor = model.geom(GROUND_GEOM)
    assert floor.type[0] == mujoco.mjtGeom.mjGEOM_PLANE
    np.testing.assert_allclose(model.geom_friction[:, 0], 0.7)  # authored so: the floor's GroundCfg, the rest alike
    # the options are those apply_physics writes for walk_physics, not the robot file's
    spec = new_scene()
    add_robot(spec, RobotCfg(file="humanoid"))
    add_ground(spec, GroundCfg())
    ref = compile_scene(spec, walk_physics(0.004))
    assert isinstance(walk_physics(), PhysicsCfg)
    for name in ("timestep", "integrator", "solver", "iterations", "ls_iterations", "cone", "tolerance"):
        assert getattr(model.opt, name) == getattr(ref.opt, name), name
    assert model.nkey == 0  # compiled once, with no keyframe
    knee = model.jnt_qposadr[robot.joint_model_ids("left_knee")[0]]
    world.engine.qpos[:, knee] = 0.0
    world.sim.reset()  # restores the Entity's initial state
    home = world.engine.qpos[0].numpy()
    assert home[knee] == pytest.approx(0.4)  # the crouched ready pose of the keyframe, not qpos0 (straight knees)
    np.testing.assert_array_equal(home, world.home_qpos)
    assert home[robot.free_qpos_adr + 2] == pytest.approx(0.90405326)  # soles on the floor


def test_the_controller_finds_the_robot_by_name_not_by_body_index():
    """A humanoid that is not body 1 and not at walk_model's prim path (a box and another prim
    come first) gets the same IK solution, relative to its root: nothing assumes index or name."""
    from ambulo.core import GroundCfg, RobotCfg, add_ground, add_robot, compile_scene, new_scene

    spec = new_scene()
    add_ground(spec, GroundCfg())
    box = spec.worldbody.add_body(name="/World/crate", pos=[3.0, 3.0, 0.2])
    box.add_freejoint()
    box.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.2, 0.2, 0.2], mass=5.0)
    add_robot(spec, RobotCfg(file="humanoid", prim_path="/World/Fancy_Humanoid"))
    model = compile_scene(spec, walk_physics())
    robot = walk_robot(model, "/World/Fancy_Humanoid")
    assert robot.root_body_id > 1 and robot.free_qpos_adr == 7
    com = np.array([0.05, 0.03, 0.80])
    feet = np.array([[0.15, 0.10, 0.05, 0.2], [-0.02, -0.09, 0.0, -0.1]])
    q0 = model.qpos0.copy()
    q0[7:] = start_walk_world().home_qpos  # its humanoid's qpos (28: free joint, 21 hinges) in the home pose
    q, err = WalkIK(model, "/World/Fancy_Humanoid").solve(q0, com, 0.05, feet)
    assert err < 1e-6
    np.testing.assert_array_equal(q[:7], q0[:7])  # the crate did not move
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.subtree_com[robot.root_body_id], com, atol=1e-6)
    np.testing.assert_allclose(data.site_xpos[robot.site_id("left_sole")], feet[0, :3], atol=1e-6)
    with pytest.raises(KeyError, match="no site 'nose'"):
        robot.site_id("nose")
