"""isaacgym tensor layouts: what a script writes through gymtorch views is ambulo's state, and back.

The robot is asymmetric on purpose (a left arm of two joints about different axes, a right arm of
one, different limits) so a swapped DOF or body order, or a w-first quaternion, shows up.
"""

import math

import numpy as np
import pytest
import torch

from ambulo.isaac.gym import gymapi, gymtorch
from ambulo.isaac.gym.gym import DOMAIN_ENV

ROBOT = """<mujoco model="lopsided">
  <compiler angle="radian"/>
  <worldbody>
    <body name="base" pos="0 0 0.5">
      <freejoint name="root"/>
      <geom type="box" size="0.2 0.1 0.05" mass="4"/>
      <body name="left_upper" pos="0 0.15 0">
        <joint name="left_shoulder" type="hinge" axis="0 1 0" range="-1.5 1.5"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.03" mass="0.5"/>
        <body name="left_lower" pos="0.2 0 0">
          <joint name="left_elbow" type="hinge" axis="0 0 1" range="-0.5 2.0"/>
          <geom type="capsule" fromto="0 0 0 0.15 0 0" size="0.025" mass="0.3"/>
        </body>
      </body>
      <body name="right_upper" pos="0 -0.15 0">
        <joint name="right_shoulder" type="hinge" axis="1 0 0" range="-1.0 0.3"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.03" mass="0.7"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""
NUM_ENVS = 3


@pytest.fixture
def gym_sim(tmp_path):
    (tmp_path / "lopsided.xml").write_text(ROBOT)
    gym = gymapi.acquire_gym()
    params = gymapi.SimParams()
    params.up_axis = gymapi.UP_AXIS_Z
    params.gravity = gymapi.Vec3(0.0, 0.0, -9.81)
    params.dt, params.substeps = 0.01, 2
    sim = gym.create_sim(0, 0, gymapi.SIM_PHYSX, params)
    options = gymapi.AssetOptions()
    options.default_dof_drive_mode = gymapi.DOF_MODE_POS
    asset = gym.load_asset(sim, str(tmp_path), "lopsided.xml", options)
    envs = []
    for i in range(NUM_ENVS):
        env = gym.create_env(sim, gymapi.Vec3(-1.0, -1.0, 0.0), gymapi.Vec3(1.0, 1.0, 1.0), 2)
        pose = gymapi.Transform(gymapi.Vec3(0.0, 0.0, 1.0 + 0.1 * i))
        actor = gym.create_actor(env, asset, pose, "robot", i, 0)
        props = gym.get_actor_dof_properties(env, actor)
        props["stiffness"], props["damping"] = 50.0, 2.0
        gym.set_actor_dof_properties(env, actor, props)
        envs.append(env)
    gym.prepare_sim(sim)
    return gym, sim, asset, envs


def test_names_and_counts_follow_the_file(gym_sim):
    gym, sim, asset, envs = gym_sim
    assert gym.get_asset_dof_names(asset) == ["left_shoulder", "left_elbow", "right_shoulder"]
    assert gym.get_asset_rigid_body_names(asset) == ["base", "left_upper", "left_lower", "right_upper"]
    assert gym.get_sim_dof_count(sim) == 3 * NUM_ENVS and gym.get_sim_rigid_body_count(sim) == 4 * NUM_ENVS
    props = gym.get_asset_dof_properties(asset)
    np.testing.assert_allclose(props["lower"], [-1.5, -0.5, -1.0])
    np.testing.assert_allclose(props["upper"], [1.5, 2.0, 0.3])
    # env 3 of a 2-per-row grid of 2 m envs sits at column 1, row 1... env 2 at column 0, row 1
    origin = gym.get_env_origin(envs[2])
    assert (origin.x, origin.y) == (0.0, 2.0)
    assert gym.find_actor_rigid_body_index(envs[1], 0, "left_lower", gymapi.DOMAIN_SIM) == 4 + 2
    assert gym.find_actor_dof_index(envs[2], 0, "right_shoulder", DOMAIN_ENV) == 2


def test_a_state_written_through_gymtorch_is_the_entity_state(gym_sim):
    gym, sim, asset, envs = gym_sim
    entity = sim.entities[0]
    root = gymtorch.wrap_tensor(gym.acquire_actor_root_state_tensor(sim))
    dofs = gymtorch.wrap_tensor(gym.acquire_dof_state_tensor(sim))
    assert root.shape == (NUM_ENVS, 13) and dofs.shape == (3 * NUM_ENVS, 2)
    before = entity.data.root_pos_w.clone()
    s = math.sin(math.pi / 4)
    origin = torch.tensor(envs[1].origin, dtype=torch.float32)
    root[1, 0:3] = origin + torch.tensor([0.1, 0.2, 0.5])
    root[1, 3:7] = torch.tensor([0.0, 0.0, s, s])  # x, y, z, w: 90 degrees about z
    root[1, 7:10] = torch.tensor([1.0, 2.0, 3.0])
    root[1, 10:13] = torch.tensor([0.3, -0.2, 0.1])
    dofs[3:6, 0] = torch.tensor([0.4, -0.3, 0.2])  # env 1: left_shoulder, left_elbow, right_shoulder
    dofs[3:6, 1] = torch.tensor([1.5, -2.5, 0.5])
    ids = gymtorch.unwrap_tensor(torch.tensor([1], dtype=torch.int32))
    gym.set_actor_root_state_tensor_indexed(sim, gymtorch.unwrap_tensor(root), ids, 1)
    gym.set_dof_state_tensor_indexed(sim, gymtorch.unwrap_tensor(dofs), ids, 1)

    d = entity.data
    torch.testing.assert_close(d.root_pos_w[1], torch.tensor([0.1, 0.2, 0.5], dtype=torch.float64))
    torch.testing.assert_close(d.root_quat_w[1], torch.tensor([s, 0.0, 0.0, s], dtype=torch.float64))  # w first
    torch.testing.assert_close(d.root_lin_vel_w[1], torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64))
    torch.testing.assert_close(d.root_ang_vel_w[1], torch.tensor([0.3, -0.2, 0.1], dtype=torch.float64))
    pos, vel = d.joint_pos[1], d.joint_vel[1]
    for name, p, v in (("left_shoulder", 0.4, 1.5), ("left_elbow", -0.3, -2.5), ("right_shoulder", 0.2, 0.5)):
        j = entity.joint_names.index(name)
        assert pos[j].item() == pytest.approx(p, abs=1e-6) and vel[j].item() == pytest.approx(v, abs=1e-6)
    # the other envs were not written
    torch.testing.assert_close(d.root_pos_w[[0, 2]], before[[0, 2]])


def test_the_entity_state_reads_back_through_gymtorch(gym_sim):
    gym, sim, asset, envs = gym_sim
    entity = sim.entities[0]
    s = math.sin(math.pi / 6)
    quat_wxyz = torch.tensor([[math.cos(math.pi / 6), s, 0.0, 0.0]] * NUM_ENVS, dtype=torch.float64)  # 60 deg about x
    entity.write_root_pose(pos_w=torch.tensor([[0.5, -0.4, 0.8]] * NUM_ENVS, dtype=torch.float64), quat_w=quat_wxyz)
    joints = torch.tensor([[0.1, 0.7, -0.6]] * NUM_ENVS, dtype=torch.float64)
    order = [entity.joint_names.index(n) for n in ("left_shoulder", "left_elbow", "right_shoulder")]
    entity.write_joint_state(pos=joints[:, order].clone())
    sim.engine.forward()
    for refresh in ("actor_root_state", "dof_state", "rigid_body_state"):
        getattr(gym, f"refresh_{refresh}_tensor")(sim)
    root = gymtorch.wrap_tensor(gym.acquire_actor_root_state_tensor(sim))
    dofs = gymtorch.wrap_tensor(gym.acquire_dof_state_tensor(sim))
    bodies = gymtorch.wrap_tensor(gym.acquire_rigid_body_state_tensor(sim))
    origins = torch.tensor(np.array([e.origin for e in envs]), dtype=torch.float32)
    torch.testing.assert_close(root[:, 0:3], origins + torch.tensor([0.5, -0.4, 0.8]))
    torch.testing.assert_close(root[:, 3:7], torch.tensor([[s, 0.0, 0.0, math.cos(math.pi / 6)]] * NUM_ENVS))
    torch.testing.assert_close(dofs[:, 0].view(NUM_ENVS, 3), joints.float())
    # rigid bodies: env-major, the asset's body order; the base's row is the root's pose
    assert bodies.shape == (4 * NUM_ENVS, 13)
    torch.testing.assert_close(bodies.view(NUM_ENVS, 4, 13)[:, 0, :7], root[:, :7])
    lower = gym.find_actor_rigid_body_index(envs[2], 0, "left_lower", gymapi.DOMAIN_SIM)
    b = entity.body_names.index("left_lower")
    torch.testing.assert_close(bodies[lower, 0:3], (entity.data.body_pos_w[2, b] + origins[2].double()).float())


def test_position_targets_drive_the_dof_they_name(gym_sim):
    gym, sim, asset, envs = gym_sim
    targets = torch.zeros(3 * NUM_ENVS)
    elbow = gym.find_actor_dof_index(envs[0], 0, "left_elbow", gymapi.DOMAIN_SIM)
    targets[elbow] = 1.0  # env 0's left elbow only
    gym.set_dof_position_target_tensor(sim, gymtorch.unwrap_tensor(targets))
    for _ in range(40):
        gym.simulate(sim)
        gym.fetch_results(sim, True)
    gym.refresh_dof_state_tensor(sim)
    pos = gymtorch.wrap_tensor(gym.acquire_dof_state_tensor(sim))[:, 0]
    assert pos[elbow].item() == pytest.approx(1.0, abs=0.1)
    others = torch.cat([pos[:elbow], pos[elbow + 1:]])
    assert others.abs().max().item() < 0.3
    gym.refresh_net_contact_force_tensor(sim)
    contacts = gymtorch.wrap_tensor(gym.acquire_net_contact_force_tensor(sim))
    assert contacts.shape == (4 * NUM_ENVS, 3)


def test_friction_and_mass_set_per_env_reach_that_world_only(gym_sim):
    gym, sim, asset, envs = gym_sim
    shapes = gym.get_actor_rigid_shape_properties(envs[1], 0)
    assert len(shapes) == gym.get_asset_rigid_shape_count(asset) == 4
    for shape in shapes:
        shape.friction = 0.25
    gym.set_actor_rigid_shape_properties(envs[1], 0, shapes)
    bodies = gym.get_actor_rigid_body_properties(envs[2], 0)
    assert bodies[0].mass == pytest.approx(4.0)  # the base box
    bodies[0].mass = 6.0
    gym.set_actor_rigid_body_properties(envs[2], 0, bodies, True)
    entity = sim.entities[0]
    geoms = torch.as_tensor(np.flatnonzero(np.isin(sim.engine.model.geom_bodyid, entity._body_ids_np)))
    friction = sim.engine.model_field("geom_friction")[:, geoms, 0]
    assert torch.all(friction[1] == 0.25) and torch.all(friction[[0, 2]] == 1.0)
    torch.testing.assert_close(entity.data.body_mass[:, 0], torch.tensor([4.0, 4.0, 6.0], dtype=torch.float64))


def test_two_actors_per_env_index_env_major_actor_minor(tmp_path):
    """Isaac's actor index is env * actors_per_env + actor; DOF rows follow the same order."""
    from ambulo import assets

    (tmp_path / "lopsided.xml").write_text(ROBOT)
    gym = gymapi.acquire_gym()
    params = gymapi.SimParams()
    params.up_axis, params.gravity = gymapi.UP_AXIS_Z, gymapi.Vec3(0.0, 0.0, -9.81)
    sim = gym.create_sim(0, 0, gymapi.SIM_PHYSX, params)
    fixed = gymapi.AssetOptions()
    fixed.fix_base_link = True
    cartpole = gym.load_asset(sim, str(tmp_path.parent), assets.path("cartpole"), fixed)
    robot = gym.load_asset(sim, str(tmp_path), "lopsided.xml", gymapi.AssetOptions())
    envs = []
    for i in range(2):
        env = gym.create_env(sim, gymapi.Vec3(-2.0, -2.0, 0.0), gymapi.Vec3(2.0, 2.0, 2.0), 2)
        gym.create_actor(env, cartpole, gymapi.Transform(gymapi.Vec3(0.0, 0.0, 2.0)), "cartpole", i, 0)
        gym.create_actor(env, robot, gymapi.Transform(gymapi.Vec3(1.0, 0.0, 1.0)), "robot", i, 0)
        envs.append(env)
    gym.prepare_sim(sim)
    cart_dofs = gym.get_asset_dof_count(cartpole)
    assert gym.get_actor_index(envs[1], 1, gymapi.DOMAIN_SIM) == 3
    root = gymtorch.wrap_tensor(gym.acquire_actor_root_state_tensor(sim))
    assert root.shape == (4, 13)
    torch.testing.assert_close(root[2, 0:3], torch.tensor([*envs[1].origin[:2], 2.0], dtype=torch.float32))  # the cart
    root[3, 0:3] = torch.tensor([*envs[1].origin[:2], 0.0]) + torch.tensor([0.3, -0.3, 0.7])
    gym.set_actor_root_state_tensor_indexed(sim, gymtorch.unwrap_tensor(root),
                                            gymtorch.unwrap_tensor(torch.tensor([3], dtype=torch.int32)), 1)
    cart, lopsided = sim.entities
    torch.testing.assert_close(lopsided.data.root_pos_w[:, 0:3],
                               torch.tensor([[1.0, 0.0, 1.0], [0.3, -0.3, 0.7]], dtype=torch.float64), atol=1e-5, rtol=0)
    dofs = gymtorch.wrap_tensor(gym.acquire_dof_state_tensor(sim))
    assert dofs.shape == (2 * (cart_dofs + 3), 2)
    dofs[:, 0] = torch.arange(dofs.shape[0], dtype=torch.float32) / 100
    gym.set_dof_state_tensor(sim, gymtorch.unwrap_tensor(dofs))
    per_env = cart_dofs + 3
    torch.testing.assert_close(cart.data.joint_pos[1].float(), dofs[per_env:per_env + cart_dofs, 0])
    torch.testing.assert_close(lopsided.data.joint_pos[0].float(), dofs[cart_dofs:per_env, 0])


def test_the_headless_viewer_writes_what_its_camera_sees(tmp_path):
    import imageio.v3 as iio

    gym = gymapi.acquire_gym()
    params = gymapi.SimParams()
    params.up_axis, params.gravity = gymapi.UP_AXIS_Z, gymapi.Vec3(0.0, 0.0, -9.81)
    sim = gym.create_sim(0, 0, gymapi.SIM_PHYSX, params)
    gym.add_ground(sim, gymapi.PlaneParams())
    asset = gym.load_asset(sim, "assets", "humanoid.urdf", gymapi.AssetOptions())  # the bundled humanoid stands in
    env = gym.create_env(sim, gymapi.Vec3(-1.0, -1.0, 0.0), gymapi.Vec3(1.0, 1.0, 1.0), 1)
    gym.create_actor(env, asset, gymapi.Transform(gymapi.Vec3(0.0, 0.0, 1.0)), "humanoid", 0, 0)
    gym.prepare_sim(sim)
    viewer = gym.create_viewer(sim, gymapi.CameraProperties())
    assert not gym.query_viewer_has_closed(viewer)
    gym.draw_viewer(viewer, sim, True)
    images = []
    for target_z in (1.0, 50.0):  # at the humanoid and the ground, then up at the (black) sky
        gym.viewer_camera_look_at(viewer, env, gymapi.Vec3(3.0, 3.0, 1.5), gymapi.Vec3(0.0, 0.0, target_z))
        path = tmp_path / f"frame_{target_z:g}.png"
        gym.write_viewer_image_to_file(viewer, str(path))
        images.append(iio.imread(path))
    assert images[0].shape == (960, 1280, 3)
    assert images[0].mean() > 20.0 and images[1].mean() < images[0].mean() / 4


def test_a_body_force_pushes_for_one_simulate_only(gym_sim):
    gym, sim, asset, envs = gym_sim
    forces = torch.zeros(4 * NUM_ENVS, 3)
    forces[4 * 1, 0] = 200.0  # env 1's base, +x (sim frame)
    gym.apply_rigid_body_force_tensors(sim, gymtorch.unwrap_tensor(forces), None, gymapi.ENV_SPACE)
    gym.simulate(sim)
    vx = sim.entities[0].data.root_lin_vel_w[:, 0].clone()
    # 200 N on 5.5 kg for 0.01 s: about 0.36 m/s, in env 1 only
    assert vx[1].item() == pytest.approx(200.0 / 5.5 * 0.01, rel=0.15) and vx[[0, 2]].abs().max().item() < 1e-6
    gym.simulate(sim)  # no force any more: x velocity holds (free fall, no contact)
    assert sim.entities[0].data.root_lin_vel_w[1, 0].item() == pytest.approx(vx[1].item(), rel=0.05)
