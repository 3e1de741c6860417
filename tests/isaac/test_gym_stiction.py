"""Static friction holds as PhysX's does: a box pushed sideways below its friction limit stays put
(MuJoCo's soft contacts let it creep unless the friction cone is made stiff: ``sim.STICTION_IMPRATIO``)."""

import torch

from ambulo.isaac.gym import gymapi, gymtorch

BOX = """<mujoco><worldbody><body name="box"><freejoint/>
  <geom type="box" size="0.1 0.1 0.1" mass="1"/></body></worldbody></mujoco>"""


def test_a_box_pushed_below_its_friction_limit_does_not_creep(tmp_path):
    (tmp_path / "box.xml").write_text(BOX)
    gym = gymapi.acquire_gym()
    params = gymapi.SimParams()
    params.up_axis, params.gravity, params.dt, params.substeps = gymapi.UP_AXIS_Z, gymapi.Vec3(0, 0, -9.81), 0.005, 1
    sim = gym.create_sim(0, -1, gymapi.SIM_PHYSX, params)
    gym.add_ground(sim, gymapi.PlaneParams())  # friction 1: the box slides above 9.81 N
    asset = gym.load_asset(sim, str(tmp_path), "box.xml", gymapi.AssetOptions())
    env = gym.create_env(sim, gymapi.Vec3(), gymapi.Vec3(), 1)
    gym.create_actor(env, asset, gymapi.Transform(gymapi.Vec3(0.0, 0.0, 0.1)), "box", 0, 0, 0)
    gym.prepare_sim(sim)
    root = gymtorch.wrap_tensor(gym.acquire_actor_root_state_tensor(sim))
    for _ in range(40):  # settle
        gym.simulate(sim)
    gym.refresh_actor_root_state_tensor(sim)
    x0 = float(root[0, 0])
    push = torch.tensor([[6.0, 0.0, 0.0]])  # 60 % of the friction limit
    for _ in range(400):  # 2 s
        gym.apply_rigid_body_force_tensors(sim, gymtorch.unwrap_tensor(push), None, gymapi.ENV_SPACE)
        gym.simulate(sim)
    gym.refresh_actor_root_state_tensor(sim)
    assert abs(float(root[0, 0]) - x0) < 1e-3
