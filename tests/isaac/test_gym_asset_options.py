"""AssetOptions legged_gym sets, through the calls it makes: a tiny URDF shaped like a quadruped's leg.

base --fixed--> shell (mass only), base --revolute KFE--> shank --fixed, dont_collapse--> foot.
With ``collapse_fixed_joints`` Isaac Gym reports 3 bodies (base with the shell merged in, shank,
foot), a cylinder shank becomes a capsule with ``replace_cylinder_with_capsule``, and the DOF
properties carry the URDF's effort and velocity limits.
"""

import mujoco
import numpy as np
import pytest
import torch

from ambulo.isaac.gym import gymapi, gymtorch

URDF = """<robot name="leg">
  <link name="base">
    <collision><geometry><box size="0.4 0.2 0.1"/></geometry></collision>
    <inertial><mass value="4.0"/><inertia ixx="0.02" iyy="0.06" izz="0.07" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="base_shell" type="fixed"><parent link="base"/><child link="shell"/></joint>
  <link name="shell">
    <inertial><mass value="1.5"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="KFE" type="revolute">
    <parent link="base"/><child link="shank"/><origin xyz="0.2 0 -0.05"/><axis xyz="0 1 0"/>
    <limit effort="55.0" velocity="7.5"/>
  </joint>
  <link name="shank">
    <collision><origin xyz="0 0 -0.1"/><geometry><cylinder length="0.2" radius="0.02"/></geometry></collision>
    <visual><geometry><box size="0.01 0.01 0.01"/></geometry></visual>
    <inertial><mass value="0.5"/><inertia ixx="0.001" iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="shank_foot" type="fixed" dont_collapse="true">
    <parent link="shank"/><child link="foot"/><origin xyz="0 0 -0.2"/>
  </joint>
  <link name="foot">
    <collision><geometry><sphere radius="0.03"/></geometry></collision>
    <inertial><mass value="0.1"/><inertia ixx="0.0001" iyy="0.0001" izz="0.0001" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
</robot>
"""


def _options(collapse: bool) -> gymapi.AssetOptions:
    options = gymapi.AssetOptions()
    options.collapse_fixed_joints = collapse
    options.replace_cylinder_with_capsule = collapse
    options.default_dof_drive_mode = gymapi.DOF_MODE_EFFORT
    options.armature = 0.01
    return options


@pytest.fixture
def gym_and_sim(tmp_path):
    (tmp_path / "leg.urdf").write_text(URDF)
    gym = gymapi.acquire_gym()
    params = gymapi.SimParams()
    params.up_axis, params.gravity = gymapi.UP_AXIS_Z, gymapi.Vec3(0.0, 0.0, -9.81)
    return gym, gym.create_sim(0, -1, gymapi.SIM_PHYSX, params), str(tmp_path)


def test_collapse_merges_fixed_links_but_keeps_dont_collapse(gym_and_sim):
    gym, sim, root = gym_and_sim
    asset = gym.load_asset(sim, root, "leg.urdf", _options(collapse=True))
    assert gym.get_asset_rigid_body_names(asset) == ["base", "shank", "foot"]
    masses = asset.model.body_mass[asset.names.body_ids]
    np.testing.assert_allclose(masses, [5.5, 0.5, 0.1])  # the shell's 1.5 kg is in the base
    # only collision geoms are shapes (the shank's visual box is not), the cylinder is a capsule
    assert gym.get_asset_rigid_shape_count(asset) == 3
    types = asset.model.geom_type[asset.shape_geom_ids]
    assert list(types) == [mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_SPHERE]


def test_without_collapse_every_link_is_a_body(gym_and_sim):
    gym, sim, root = gym_and_sim
    asset = gym.load_asset(sim, root, "leg.urdf", _options(collapse=False))
    assert gym.get_asset_rigid_body_names(asset) == ["base", "shell", "shank", "foot"]
    assert mujoco.mjtGeom.mjGEOM_CYLINDER in asset.model.geom_type[asset.shape_geom_ids]


def test_dof_properties_carry_the_urdf_limits_and_armature(gym_and_sim):
    gym, sim, root = gym_and_sim
    props = gym.get_asset_dof_properties(gym.load_asset(sim, root, "leg.urdf", _options(collapse=True)))
    assert props["effort"][0] == pytest.approx(55.0) and props["velocity"][0] == pytest.approx(7.5)
    assert props["driveMode"][0] == gymapi.DOF_MODE_EFFORT and props["armature"][0] == pytest.approx(0.01)


def test_collapsed_actor_in_the_batched_model_reports_foot_contact(gym_and_sim):
    """legged_gym's loop: per-env friction through set_asset_rigid_shape_properties with a tensor
    value, then effort-mode torques as an (envs, dofs) tensor; the foot (a body only because of
    dont_collapse) carries the weight in the contact-force tensor, indexed by its rigid body handle."""
    gym, sim, root = gym_and_sim
    gym.add_ground(sim, gymapi.PlaneParams())
    asset = gym.load_asset(sim, root, "leg.urdf", _options(collapse=True))
    shape_props = gym.get_asset_rigid_shape_properties(asset)
    envs = []
    for i in range(2):
        env = gym.create_env(sim, gymapi.Vec3(), gymapi.Vec3(), 2)
        for p in shape_props:
            p.friction = torch.tensor([0.4 + 0.5 * i])  # legged_gym assigns a 1-element tensor
        gym.set_asset_rigid_shape_properties(asset, shape_props)
        gym.create_actor(env, asset, gymapi.Transform(gymapi.Vec3(3.0 * i, 0.0, 0.35)), "leg", i, 0, 0)
        envs.append(env)
    gym.prepare_sim(sim)
    friction = sim.engine.model_field("geom_friction")
    foot = gym.find_actor_rigid_body_handle(envs[1], 0, "foot")
    assert foot == 2
    foot_geom = [g for g in range(sim.engine.model.ngeom) if sim.engine.model.geom_bodyid[g] == sim.entities[0].body_ids[foot]]
    # PhysX averages the foot's friction with the ground's (1.0); MuJoCo is given that average
    np.testing.assert_allclose(friction[:, foot_geom[0], 0].cpu().numpy(), [0.7, 0.95], atol=1e-6)
    assert gym.get_actor_rigid_shape_properties(envs[0], 0)[-1].friction == pytest.approx(0.4)
    contact = gymtorch.wrap_tensor(gym.acquire_net_contact_force_tensor(sim)).view(2, -1, 3)
    dof = gymtorch.wrap_tensor(gym.acquire_dof_state_tensor(sim)).view(2, 1, 2)
    for _ in range(200):  # the leg held straight by torques computed here, as legged_gym's PD does
        gym.refresh_dof_state_tensor(sim)
        torques = -50.0 * dof[..., 0] - 2.0 * dof[..., 1]  # (envs, dofs): Isaac takes any tensor of the buffer's size
        gym.set_dof_actuation_force_tensor(sim, gymtorch.unwrap_tensor(torques))
        gym.simulate(sim)
    gym.refresh_net_contact_force_tensor(sim)
    assert (contact[:, foot, 2] > 0.5).all()  # the foot touches the ground and is pushed up
