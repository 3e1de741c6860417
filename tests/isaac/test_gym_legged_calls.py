"""Calls legged_gym makes that other Isaac Gym scripts do not: its sim config dict, and DOF
tensors passed as (envs, dofs) where Isaac reads the flat (num_dofs,) buffer."""

import pytest
import torch

from ambulo.isaac.gym import gymapi, gymtorch, gymutil

LEGGED_GYM_SIM = {  # class_to_dict(LeggedRobotCfg.sim), as legged_gym's helpers build it
    "dt": 0.005, "substeps": 1, "gravity": [0.0, 0.0, -9.81], "up_axis": 1,
    "physx": {"num_threads": 10, "solver_type": 1, "num_position_iterations": 4, "num_velocity_iterations": 0,
              "contact_offset": 0.01, "rest_offset": 0.0, "bounce_threshold_velocity": 0.5,
              "max_depenetration_velocity": 1.0, "max_gpu_contact_pairs": 2 ** 23,
              "default_buffer_size_multiplier": 5, "contact_collection": 2},
}

ARM = """<mujoco><worldbody><body name="base" pos="0 0 1">
  <geom type="box" size="0.1 0.1 0.1" mass="1"/>
  <body name="a"><joint name="j0" axis="0 0 1"/><geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02" mass="0.2"/>
  <body name="b" pos="0.2 0 0"><joint name="j1" axis="0 0 1"/><geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02" mass="0.2"/>
  <body name="c" pos="0.2 0 0"><joint name="j2" axis="0 0 1"/><geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02" mass="0.2"/>
  </body></body></body></body></worldbody></mujoco>"""


def test_parse_sim_config_reads_legged_gyms_sim_section():
    params = gymapi.SimParams()
    gymutil.parse_sim_config(LEGGED_GYM_SIM, params)
    assert params.dt == 0.005 and params.substeps == 1 and params.up_axis == gymapi.UP_AXIS_Z
    assert (params.gravity.x, params.gravity.y, params.gravity.z) == (0.0, 0.0, -9.81)
    assert params.physx.num_threads == 10 and params.physx.contact_offset == 0.01
    with pytest.raises(ValueError, match="physx.num_treads"):
        gymutil.parse_sim_config({"physx": {"num_treads": 2}}, params)


def test_actuation_forces_as_envs_by_dofs_reach_each_dof(tmp_path):
    (tmp_path / "arm.xml").write_text(ARM)
    gym = gymapi.acquire_gym()
    params = gymapi.SimParams()
    gymutil.parse_sim_config(LEGGED_GYM_SIM, params)
    sim = gym.create_sim(0, -1, gymapi.SIM_PHYSX, params)
    options = gymapi.AssetOptions()
    options.default_dof_drive_mode = gymapi.DOF_MODE_EFFORT  # the file has no free joint: its base is fixed
    asset = gym.load_asset(sim, str(tmp_path), "arm.xml", options)
    for _ in range(2):
        env = gym.create_env(sim, gymapi.Vec3(), gymapi.Vec3(), 2)
        gym.create_actor(env, asset, gymapi.Transform(), "arm", 0, 0, 0)
    gym.prepare_sim(sim)
    torques = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # legged_gym's self.torques: (envs, dofs)
    gym.set_dof_actuation_force_tensor(sim, gymtorch.unwrap_tensor(torques))
    for _ in range(10):
        gym.simulate(sim)
    gym.refresh_dof_state_tensor(sim)
    vel = gymtorch.wrap_tensor(gym.acquire_dof_state_tensor(sim)).view(2, 3, 2)[..., 1]
    assert vel[0, 0] > 0.1 and vel[1, 2] < -0.1  # env 0 turns its first joint, env 1 its last
    assert abs(float(vel[1, 0])) < abs(float(vel[1, 2]))
    with pytest.raises(ValueError, match="shape"):
        gym.set_dof_actuation_force_tensor(sim, gymtorch.unwrap_tensor(torch.zeros(2, 2)))


def test_quat_apply_reads_both_arguments_as_flat_lists():
    """legged_gym's quat_apply_yaw passes (envs * points, 4) quaternions and (envs, points, 3) points."""
    from ambulo.isaac.gym import torch_utils

    yaw = torch.tensor([[0.0, 0.0, 1.0, 0.0]]).repeat(6, 1)  # 180 degrees about z, xyzw
    points = torch.arange(18.0).view(2, 3, 3)
    out = torch_utils.quat_apply(yaw, points)
    assert out.shape == (2, 3, 3)
    torch.testing.assert_close(out[..., :2], -points[..., :2])
    torch.testing.assert_close(out[..., 2], points[..., 2])
