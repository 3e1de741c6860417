"""policies.WalkingPolicy runs the shipped network on a bare ``Entity``: here the humanoid-walk
task's own robot, N worlds at once, with no Isaac-style ``World`` around it."""

import pytest
import torch

from ambulo import envs
from ambulo.policies import WalkingPolicy, load_policy

pytest.importorskip("onnxruntime")


@pytest.fixture(scope="module")
def env():
    env = envs.make("humanoid-walk", play=True, num_envs=3, seed=5)
    yield env
    env.close()


def stepped_off_default(env):
    gen = torch.Generator().manual_seed(1)
    for _ in range(5):  # joints and base moving, a non-zero last action
        env.step(0.5 * torch.randn(env.num_envs, env.num_actions, generator=gen))
    env.commands.command[:] = torch.tensor([[0.5, 0.0, 0.2], [0.0, -0.3, 0.0], [-0.4, 0.1, -0.6]])


def test_observation_on_the_tasks_entity_is_the_tasks_own_in_every_world(env):
    stepped_off_default(env)
    walker = WalkingPolicy(env.robot)
    walker.actions = env.actions.cpu().clone()
    got = walker.observation(env.commands.command.cpu())
    assert got.shape == (env.num_envs, env.num_obs)
    torch.testing.assert_close(got, env._compute_observations().cpu(), atol=1e-6, rtol=1e-6)


def test_forward_sets_the_contracts_targets_from_the_network_each_control_period(env):
    stepped_off_default(env)
    walker = WalkingPolicy(env.robot)
    c = walker.contract
    command = env.commands.command.cpu().clone()
    obs = walker.observation(command)
    walker.forward(c["physics_dt_s"], command)
    torch.testing.assert_close(walker.actions, load_policy(c["task"])(obs))
    targets = torch.tensor(c["default_joint_pos"], dtype=torch.float64) + c["action_scale"] * walker.actions.double()
    ctrl_by_walker = env.engine.ctrl.clone()
    env.robot.set_joint_targets(targets.to(env.robot.device, env.engine.dtype))
    torch.testing.assert_close(ctrl_by_walker, env.engine.ctrl)
    # between control periods the targets stay: no network call, no write
    env.engine.ctrl.zero_()
    decimation = round(c["control_dt_s"] / c["physics_dt_s"])
    for _ in range(decimation - 1):
        walker.forward(c["physics_dt_s"], command)
    assert not env.engine.ctrl.any()
    walker.forward(c["physics_dt_s"], command)
    assert env.engine.ctrl.any()


def test_reset_stands_every_world_in_the_default_pose(env):
    stepped_off_default(env)
    walker = WalkingPolicy(env.robot)
    walker.actions.fill_(1.0)
    walker.reset()
    data, c = env.robot.data, walker.contract
    expected = torch.tensor(c["default_joint_pos"], dtype=data.joint_pos.dtype).expand(env.num_envs, -1)
    torch.testing.assert_close(data.joint_pos.cpu(), expected)
    assert not data.joint_vel.any()
    torch.testing.assert_close(data.root_pos_w[:, 2].cpu(),
                               torch.full((env.num_envs,), c["default_root_height_m"], dtype=data.joint_pos.dtype))
    assert not walker.actions.any()


def test_an_entity_with_other_joints_is_refused():
    cartpole = envs.make("cartpole", num_envs=1)
    with pytest.raises(ValueError, match="policy drives joints"):
        WalkingPolicy(cartpole.robot)
    cartpole.close()


def test_an_unbound_policy_says_what_it_needs():
    walker = WalkingPolicy()
    with pytest.raises(RuntimeError, match="bind"):
        walker.reset()
